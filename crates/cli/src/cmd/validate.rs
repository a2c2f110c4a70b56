//! `ipa-sysid validate`: metrics of a saved model on new data (MATLAB `compare`).

use std::path::{Path, PathBuf};

use sysid_core::format::visible;
use sysid_summary::ValidationReport;

use super::common::{check_outputs, print_report, stream_note, ColumnArgs, StreamMode};

/// Flags of `validate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Model file written by `identify --save-model` (or an `identify --json` file). A file that names
    /// the columns it was identified from (model file version 3) gives the columns read here for
    /// --u-col / --y-col not given (an explicit `--u-col u` reads u); a note says which. Its
    /// identification's warnings are repeated.
    #[arg(long, value_name = "MODEL.json")]
    pub model: PathBuf,
    /// CSV file with the validation record. Without a time column and --ts, the model's Ts is used.
    #[arg(long, value_name = "FILE")]
    pub data: PathBuf,
    #[command(flatten)]
    pub columns: ColumnArgs,
    /// The memory budget of the validation (its simulation, prediction and residual copies of the
    /// record), checked once the record is read (audit s23 H-B1).
    #[command(flatten)]
    pub memory: super::common::MemoryArgs,
    /// Lags M of the residual analysis (autocorrelation τ = 1..M, cross-correlation τ = −M..M), 1 to
    /// 1000: the independence test factors a (2M+1)² matrix (O(M²) memory, O(M³) time).
    #[arg(long, default_value_t = sysid::residuals::DEFAULT_MAX_LAG, value_name = "M",
          value_parser = super::common::parse_lags)]
    pub resid_lags: usize,
    /// Exit with code 1 when the result carries warnings (they are printed either way), without writing
    /// the output files (an earlier file there is kept).
    #[arg(long)]
    pub strict: bool,
    /// Write the metrics as JSON here (`-` for standard output).
    #[arg(long, value_name = "OUT")]
    pub json: Option<PathBuf>,
    /// Write the model's output as CSV: t,y,y_sim,y_sim_y0meas,y_pred,residual (y_sim: the simulation
    /// from the estimated initial outputs, MATLAB `compare`'s default, the "(sim., y0 est.)" fit;
    /// y_sim_y0meas: from the measured ones, the "(sim., y0 meas.)" fit — trust it when they differ;
    /// a NARX model has only the latter, in both; residual = y − y_pred; y_pred is the
    /// --horizon-step prediction; MATLAB `compare`/`predict`). t is the record's time: t0 + k·Ts, t0 the
    /// time column's value on the judged record's first row (its first --rows row; 0 without a time
    /// column). `-`: standard output; the text report
    /// then goes to standard error, and no other output may be `-`.
    #[arg(long, value_name = "FILE.csv")]
    pub out: Option<PathBuf>,
    /// Prediction horizon K in samples for y_pred and the prediction metrics (MATLAB `predict(m, z, K)`;
    /// 1 = one-step-ahead).
    #[arg(long, value_name = "K", default_value_t = 1)]
    pub horizon: usize,
    /// Score from sample K on: every figure (fit %, RMSE, loss V, FPE, AIC, MATLAB's LossFcn, FPE and
    /// nAIC, the --horizon fit, the residual tests) over the samples k >= max(K, k0) only, k0 the
    /// model's largest lag (its first predicted sample, where scoring starts without this option).
    /// K is 0-based, a row of the record as read (after --rows), as in --rows; e.g. 50 for the
    /// nonlinear_benchmarks' 50-sample state-initialisation window. The simulations and predictions
    /// are the same with or without it (run over the whole record, the initial outputs estimated on
    /// k >= k0): only the rows scored change. --out still writes every sample, with a last column
    /// `scored` (1 from sample max(K, k0) on, else 0). A K that reaches the record's end, or leaves no
    /// more samples than the model's parameters, is refused.
    #[arg(long, value_name = "K", default_value_t = 0)]
    pub score_from: usize,
    /// Read the record in passes with bounded memory (single-input models, horizon 1, no --out;
    /// docs/data.md, "Long records"): `auto` streams a CSV file of 64 MiB or more when those hold;
    /// `--stream` alone is `on`.
    #[arg(long, value_enum, default_value = "auto", num_args = 0..=1, default_missing_value = "on", value_name = "WHEN")]
    pub stream: StreamMode,
    /// The ids (field names, e.g. `u_col`) of the flags typed on the command line, a flag given at its
    /// default value included (filled by `main` from clap's matches): a model file's stored columns
    /// are read only for --u-col / --y-col not typed ([`stored_columns`]).
    #[arg(skip)]
    pub given: Vec<String>,
}

/// The column names the model file recorded ([`sysid::model::Provenance`]) put in `opts` for each of
/// --u-col / --y-col not typed (`given`: the flags typed; an explicit `--u-col u` is the user's
/// choice, not the default) when the record has a header (audit s20 L-4: a model identified from
/// `--u-col InputGasRate --y-col CO2` needed them again); a note saying which, `None` when none was
/// taken. The file's strings are printed through [`visible`].
fn stored_columns(
    provenance: Option<&sysid::model::Provenance>,
    opts: &mut sysid::data::CsvOptions,
    given: &[String],
) -> Option<String> {
    let p = provenance?;
    if opts.no_header {
        return None;
    }
    let typed = |id: &str| typed(given, id);
    let mut taken = Vec::new();
    if !typed("u_col") && !p.u_columns.is_empty() && p.u_columns.join(",") != opts.u_col {
        opts.u_col = p.u_columns.join(",");
        taken.push(format!("--u-col {}", visible(&opts.u_col)));
    }
    if let Some(y) = p
        .y_column
        .as_ref()
        .filter(|y| !typed("y_col") && **y != opts.y_col)
    {
        opts.y_col = y.clone();
        taken.push(format!("--y-col {}", visible(y)));
    }
    (!taken.is_empty()).then(|| {
        format!(
            "columns from the model file (its identification on {} read them): {}",
            visible(&p.record),
            taken.join(" ")
        )
    })
}

/// Whether the flag of id `id` (`u_col`) was typed (`given`: the ids of the flags typed).
fn typed(given: &[String], id: &str) -> bool {
    given.iter().any(|g| g == id)
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
    let model = match sysid::model_file::read_any_model(&args.model)? {
        sysid::model_file::AnyModel::Linear(m) => m,
        sysid::model_file::AnyModel::Narx(m) => {
            // A NARX model is validated in memory: --stream on is refused, not ignored (audit s27 L-9).
            decide_stream(&args, Some("a polynomial NARX model, validated in memory"))?;
            return run_narx(&args, &m, &inputs);
        }
    };
    let mut opts = args.columns.csv_options(&args.memory);
    opts.fallback_ts = Some(model.ts());
    if let Some(note) = stored_columns(model.provenance(), &mut opts, &args.given) {
        eprintln!("note: {note}");
    }
    // A model with several inputs reads one column per input: --u-col u1,u2 or the model's input names.
    let miso = model.inputs().len() > 1 || opts.u_col.contains(',');
    if miso && !opts.u_col.contains(',') {
        opts.u_col = model
            .inputs()
            .iter()
            .map(|i| i.name())
            .collect::<Vec<_>>()
            .join(",");
    }
    // A column the record lacks that came from the model file is called so (audit s22 L-N3).
    let from_model = |e: sysid::SysidError| match e {
        sysid::SysidError::MissingColumn {
            file,
            column,
            setting,
            header,
            hint,
            origin,
        } => {
            let taken = (setting == sysid::Setting::UCol && !typed(&args.given, "u_col"))
                || (setting == sysid::Setting::YCol && !typed(&args.given, "y_col"));
            let stored = model.provenance().is_some_and(|p| {
                p.u_columns.contains(&column) || p.y_column.as_deref() == Some(&column)
            });
            sysid::SysidError::MissingColumn {
                origin: if taken && stored {
                    sysid::ColumnOrigin::ModelFile
                } else {
                    origin
                },
                file,
                column,
                setting,
                header,
                hint,
            }
        }
        e => e,
    };
    let output_map = model.output_nonlinearity().is_some();
    if streaming(&args, miso, output_map)? {
        return run_streamed(&args, &model, &opts, &inputs).map_err(|e| {
            match e.downcast::<sysid::SysidError>() {
                Ok(e) => from_model(e).into(),
                Err(e) => e,
            }
        });
    }
    // A refusal for memory offers `--stream on` only where it would read this record in passes.
    if why_not_stream(&args, miso, output_map).is_none()
        && !sysid_core::data::mat::has_mat_name(&args.data)
    {
        opts.in_passes = Some("--stream on, which reads the CSV record in passes".into());
    }
    let record = sysid::data::read_record(&args.data, &opts).map_err(from_model)?;
    // The reader's notes are printed once, among the report's warnings ("data: …"; audit s18 L-6).
    let data = record.data;
    // The simulation, predictions, residuals and their analysis hold about 14 numbers per sample at
    // the peak (a 40 M-sample record took 4.38 GB; audit s23 H-B1): refused above the budget before
    // any of them is made.
    check_validate_memory(&data, model.parameter_count(), args.memory.max_memory)?;
    if data.inputs().len() != model.inputs().len() {
        anyhow::bail!(sysid::SysidError::setting(
            sysid::Setting::UCol,
            &opts.u_col,
            &format!("one column per model input ({})", model.inputs().len())
        ));
    }
    let us = data.input_signals();
    sysid::metrics::check_sampling_noted(data.name(), data.ts(), model.ts(), &record.notes)?;
    let blame = |e: sysid::SysidError| {
        // A failure may have its cause in what the reader noted (a lone outlier: audit s30 M-2): the
        // notes are printed before the error, which otherwise names no row.
        for n in super::common::data_notes(&record.notes) {
            eprintln!("warning: {n}");
        }
        blame_model(
            e.context(data.name()),
            &model,
            &args.model,
            data.name(),
            || Ok(sysid::TermSizes::of_record(&model, &us, data.y())),
        )
    };
    let mut report =
        ValidationReport::assemble_scored_from(&model, &data, args.resid_lags, args.score_from)
            .map_err(blame)?;
    report
        .warnings
        .extend(super::common::data_notes(&record.notes));
    model_warnings(
        &mut report,
        &model,
        data.name(),
        data.len(),
        &opts,
        Some(Samples::InMemory(&data)),
    );
    let out = sysid::metrics::model_output_scored_from(
        &model,
        &us,
        data.y(),
        args.horizon,
        args.score_from,
    )
    .map_err(blame)?;
    let value = report_json(&report, args.horizon, out.fit_pred_percent, &record.notes)?;
    let text = report_text(
        &args,
        &report,
        data.name(),
        data.len(),
        out.fit_pred_percent,
    );
    print_report(&text, &[args.json.as_deref(), args.out.as_deref()])?;
    let mut out_csv = None;
    if args.out.is_some() {
        // The record's own time: t0 + k·Ts from its time column's first value (audit s16 L13).
        let t0 = record.t0.unwrap_or(0.0);
        let t: Vec<f64> = sysid::data::sample_times(data.len(), data.ts())
            .into_iter()
            .map(|tk| t0 + tk)
            .collect();
        let mut w = csv::Writer::from_writer(Vec::new());
        let scored = ScoredColumn::of(args.score_from, report.score_from);
        w.write_record(scored.header())?;
        for k in 0..data.len() {
            let cell = |s: &Option<Vec<f64>>| s.as_ref().map_or(String::new(), |s| shortest(s[k]));
            w.write_record(scored.row(
                k,
                [
                    shortest(t[k]),
                    shortest(data.y()[k]),
                    cell(&out.y_sim),
                    cell(&out.y_sim_measured),
                    shortest(out.y_pred[k]),
                    shortest(data.y()[k] - out.y_pred[k]),
                ],
            ))?;
        }
        out_csv = Some(w.into_inner().map_err(|e| anyhow::anyhow!("{e}"))?);
    }
    finish(&args, report.warnings.len(), &value, out_csv, &inputs)
}

/// A cell of `validate --out`: the shortest form that reads back to the same f64, in scientific
/// notation beyond 1e16 or below 1e-5 (`sysid_core::format::Shortest`, the form of the tool's other
/// outputs; audit s32 L-4: a 1e300 prediction was written as 300 digits).
fn shortest(v: f64) -> String {
    sysid_core::format::shortest(v)
}

/// The columns of `validate --out` (linear and NARX models alike): y_sim from the estimated initial
/// outputs, y_sim_y0meas from the measured ones (audit s24 M-2: the file held only the former, the
/// figure the warning says not to trust when the two differ).
const OUT_COLUMNS: [&str; 6] = ["t", "y", "y_sim", "y_sim_y0meas", "y_pred", "residual"];

/// The last column of `validate --out` with `--score-from`: `scored`, 1 for the samples every figure is
/// over (k >= max(K, k0)), 0 before; without the option the file keeps its six columns (its readers
/// read them by position: audit s24's awk lines, docs/real-data.md).
#[derive(Clone, Copy)]
struct ScoredColumn {
    /// The first scored sample, when the column is written.
    first: Option<usize>,
}

impl ScoredColumn {
    /// The column for `--score-from asked` (0: not given, no column) of a model scored from sample
    /// `first` (max(K, k0), [`sysid::metrics::first_scored`]).
    fn of(asked: usize, first: usize) -> Self {
        ScoredColumn {
            first: (asked > 0).then_some(first),
        }
    }

    /// The header row.
    fn header(&self) -> Vec<&'static str> {
        let mut h = OUT_COLUMNS.to_vec();
        if self.first.is_some() {
            h.push("scored");
        }
        h
    }

    /// Row `k`'s cells `cells` with the column's cell when written.
    fn row(&self, k: usize, cells: [String; 6]) -> Vec<String> {
        let mut r = cells.to_vec();
        if let Some(first) = self.first {
            r.push(if k >= first { "1" } else { "0" }.into());
        }
        r
    }
}

/// The words of the summary line that say from which sample the figures are scored (`asked`: the
/// `--score-from` given, 0 when not; `first`: the first scored sample, max(K, k0); `n`: the samples
/// scored): nothing without the option (the figures start at k0 as ever).
fn scored_words(asked: usize, first: usize, n: usize) -> String {
    if asked == 0 {
        String::new()
    } else if first == asked {
        format!(", scored from sample {first} on by --score-from (0-based): {n}")
    } else {
        format!(
            ", scored from sample {first} on, the model's first predicted sample k0, after \
             --score-from {asked}: {n}"
        )
    }
}

/// `validate` of a polynomial NARX model: simulation (from the measured initial outputs) and one-step
/// metrics, the warnings (a blow-up, a negative fit, no input term), `--out` with the columns of a
/// linear model's.
fn run_narx(
    args: &Args,
    model: &sysid::narx_model::NarxModel,
    inputs: &[&Path],
) -> anyhow::Result<()> {
    if args.horizon != 1 {
        anyhow::bail!(sysid::SysidError::setting(
            sysid::Setting::Other("--horizon"),
            args.horizon,
            "1 for a polynomial NARX model (its k-step prediction is not implemented; the simulation is in y_sim)"
        ));
    }
    let mut opts = args.columns.csv_options(&args.memory);
    opts.fallback_ts = Some(model.ts());
    if let Some(note) = stored_columns(model.provenance(), &mut opts, &args.given) {
        eprintln!("note: {note}");
    }
    let record = sysid::data::read_record(&args.data, &opts)?;
    let data = record.data;
    // The same budget as a linear model's (its simulation, predictions, residuals and the `--out`
    // columns per sample): refused before any of them is made (audit s23 H-B1, session 25).
    check_validate_memory(&data, model.parameter_count(), args.memory.max_memory)?;
    sysid::metrics::check_sampling_noted(data.name(), data.ts(), model.ts(), &record.notes)?;
    let metrics = sysid::narx::narx_metrics_scored_from(model, &data, args.score_from)?;
    let first = sysid::metrics::first_scored(model.k0(), args.score_from);
    let mut warnings: Vec<String> = super::common::data_notes(&record.notes).collect();
    if let Some(k) = metrics.blew_up_at {
        warnings.insert(
            0,
            sysid::narx::blow_up_warning("validation", data.name(), k),
        );
    }
    // As for a linear model: a negative fit (a blow-up has said its own), and a model without an input.
    let poor = metrics
        .blew_up_at
        .is_none()
        .then(|| {
            sysid::Warning::if_poor_simulation(
                sysid::warnings::Record::Validation,
                metrics.fit_sim_percent,
            )
        })
        .flatten();
    warnings.extend(
        sysid::narx::no_input_warning(model.terms())
            .into_iter()
            .chain(poor)
            .map(|w| w.to_string()),
    );
    // The record's input beyond the model's estimation data, as for a linear model (audit s17 M-d).
    warnings.extend(sysid_summary::extrapolation_words(
        model.data_range(),
        ["u"],
        &[sysid::DataRange::extremes(data.u())],
    ));
    // What a linear model's file gives too (audit s33 M-1: a NARX model's held-out fit 39 points below
    // its estimation fit was validated without a word): the fit far below the one the file records on
    // its estimation record, the record being that record, and the identification's own warnings.
    warnings.extend(
        sysid::trust::held_out_drop(
            (
                sysid::warnings::Record::Estimation,
                model.provenance().and_then(|p| p.fit_estimation_percent),
            ),
            (sysid::warnings::Record::Validation, metrics.fit_sim_percent),
        )
        .map(|w| w.to_string()),
    );
    warnings.extend(in_sample_warning(
        model.provenance(),
        data.name(),
        data.len(),
        &opts,
        Some(Samples::InMemory(&data)),
    ));
    warnings.extend(
        sysid::model_file::provenance_warnings(model.provenance())
            .into_iter()
            .map(|w| format!("model: {w}")),
    );
    let fmt = |v: Option<f64>| v.map_or("n/a (the simulation blew up)".into(), report::format::num);
    let pct = |v: Option<f64>| v.map_or("n/a".into(), |v| format!("{} %", report::format::num(v)));
    let mut text = format!(
        "{} (polynomial NARX, {} terms) on {} ({} samples{}): simulation RMSE {}, fit {} (initial \
         outputs measured); one-step RMSE {}, fit {}; MATLAB's LossFcn {}, FPE {}, nAIC {} (one-step \
         prediction errors)\n",
        args.model.display(),
        model.terms().len(),
        data.name(),
        data.len(),
        scored_words(args.score_from, first, metrics.n),
        fmt(metrics.rmse_sim),
        pct(metrics.fit_sim_percent),
        report::format::num(metrics.rmse_pred),
        pct(metrics.fit_pred_percent),
        metrics.loss_fcn.map_or("n/a".into(), report::format::num),
        metrics.fpe_matlab.map_or("n/a".into(), report::format::num),
        metrics.aic_matlab.map_or("n/a".into(), report::format::num),
    );
    for w in &warnings {
        text.push_str(&format!("warning: {w}\n"));
    }
    print_report(&text, &[args.json.as_deref(), args.out.as_deref()])?;
    let mut out_csv = None;
    if args.out.is_some() {
        let sim = model.simulate(data.u(), data.y())?.y;
        let pred = model.predict(data.u(), data.y())?;
        // The record's own time: t0 + k·Ts from its time column's first value (audit s16 L13).
        let t0 = record.t0.unwrap_or(0.0);
        let t: Vec<f64> = sysid::data::sample_times(data.len(), data.ts())
            .into_iter()
            .map(|tk| t0 + tk)
            .collect();
        let mut w = csv::Writer::from_writer(Vec::new());
        let scored = ScoredColumn::of(args.score_from, first);
        w.write_record(scored.header())?;
        for k in 0..data.len() {
            let s = if sim[k].is_finite() {
                shortest(sim[k])
            } else {
                String::new()
            };
            w.write_record(scored.row(
                k,
                [
                    shortest(t[k]),
                    shortest(data.y()[k]),
                    s.clone(),
                    s,
                    shortest(pred[k]),
                    shortest(data.y()[k] - pred[k]),
                ],
            ))?;
        }
        out_csv = Some(w.into_inner().map_err(|e| anyhow::anyhow!("{e}"))?);
    }
    let value = serde_json::json!({
        "model": model,
        "score_from": first,
        "metrics": { "validation": metrics },
        "warnings": warnings,
        "data_notes": record.notes,
    });
    finish(args, warnings.len(), &value, out_csv, inputs)
}

/// Writes `--out` (its CSV `out_csv`) and `--json` together, with `--strict` (neither when the run has
/// `warnings` and `--strict` is given: [`super::common::write_outputs`]).
fn finish(
    args: &Args,
    warnings: usize,
    value: &serde_json::Value,
    out_csv: Option<Vec<u8>>,
    inputs: &[&Path],
) -> anyhow::Result<()> {
    let json = match &args.json {
        Some(_) => Some(super::common::report_json(value, true)? + "\n"),
        None => None,
    };
    let mut outputs: Vec<(&Path, &[u8], &str)> = Vec::new();
    if let (Some(path), Some(bytes)) = (&args.out, &out_csv) {
        outputs.push((path, bytes, "--out"));
    }
    if let (Some(path), Some(text)) = (&args.json, &json) {
        outputs.push((path, text.as_bytes(), "--json"));
    }
    super::common::write_outputs(&outputs, inputs, args.strict, warnings)
}

/// The `validate --json` document: the report with the horizon, the fit of its prediction and the
/// reader's notes.
fn report_json(
    report: &ValidationReport,
    horizon: usize,
    fit_horizon: Option<f64>,
    notes: &[String],
) -> anyhow::Result<serde_json::Value> {
    let mut value = serde_json::to_value(report)?;
    if let Some(obj) = value.as_object_mut() {
        obj.insert("horizon".into(), serde_json::json!(horizon));
        obj.insert(
            "fit_pred_horizon_percent".into(),
            serde_json::json!(fit_horizon),
        );
        obj.insert("data_notes".into(), serde_json::json!(notes));
    }
    Ok(value)
}

/// A fit % as the summary line prints it: two decimals, or from 1e5 on (an unstable or wildly wrong
/// model's −4e89 %) the command line's short form, `report::format::num` (6 significant digits,
/// scientific), as identify's table prints every fit (audit s30 L-3: a 90-digit percent).
fn fit_text(v: Option<f64>) -> String {
    match v {
        None => "n/a".into(),
        Some(v) if v.abs() >= 1e5 => report::format::num(v),
        Some(v) => format!("{v:.2}"),
    }
}

/// The text summary of a validation on the record `name` of `len` samples.
fn report_text(
    args: &Args,
    report: &ValidationReport,
    name: &str,
    len: usize,
    fit_horizon: Option<f64>,
) -> String {
    let m = &report.metrics.validation;
    let mut text = format!(
        "{} on {} ({} samples{}): fit {} % (simulation, initial outputs estimated), {} % (simulation, \
         initial outputs measured), {} % (1-step prediction){}; loss V {} (one-step equation error), \
         V_sim {} (simulation error), FPE {}; MATLAB's LossFcn {}, FPE {}, nAIC {} (the model's own \
         one-step prediction errors); {}\n",
        args.model.display(),
        name,
        len,
        scored_words(args.score_from, report.score_from, m.n),
        fit_text(m.fit_sim_percent),
        fit_text(m.fit_sim_measured_percent),
        fit_text(m.fit_pred_percent),
        if args.horizon > 1 {
            format!(
                ", {} % ({}-step prediction)",
                fit_text(fit_horizon),
                args.horizon
            )
        } else {
            String::new()
        },
        m.loss.map_or("n/a".into(), report::format::num),
        m.loss_sim.map_or("n/a".into(), report::format::num),
        m.fpe.map_or("n/a".into(), report::format::num),
        m.loss_fcn.map_or("n/a".into(), report::format::num),
        m.fpe_matlab.map_or("n/a".into(), report::format::num),
        m.aic_matlab.map_or("n/a".into(), report::format::num),
        // The one verdict (`Model::stability`, as identify's "Poles: … →" line and the JSON's
        // `stability`) in its short words: an integrator is not "UNSTABLE" (audit s27 L-10).
        report.model.stability().word()
    );
    text.push_str(&crate::text::residuals_text(&[(
        "validation",
        &report.residuals.validation,
    )]));
    for w in &report.warnings {
        text.push_str(&format!("warning: {w}\n"));
    }
    text
}

/// Whether to read the record in passes (`--stream`, [`StreamMode::decide`]): one input, horizon 1,
/// no `--out`, no `--resample`.
fn streaming(args: &Args, miso: bool, output_map: bool) -> anyhow::Result<bool> {
    decide_stream(args, why_not_stream(args, miso, output_map))
}

/// What these settings need the whole record for, if anything (then `--stream on` is refused and a
/// refusal for memory does not offer it).
fn why_not_stream(args: &Args, miso: bool, output_map: bool) -> Option<&'static str> {
    if miso {
        Some("a model with several inputs")
    } else if output_map {
        // The passes simulate the linear block only (audit s27 H-2): g(v) is applied in memory.
        Some(
            "a model with an output nonlinearity (Wiener, Hammerstein-Wiener), validated in memory",
        )
    } else if args.horizon > 1 {
        Some("--horizon above 1")
    } else if args.out.is_some() {
        Some("--out, which writes every sample")
    } else if args.columns.resample.is_some() {
        Some("--resample")
    } else {
        None
    }
}

/// [`common::StreamMode::decide`] for `validate`, `why` being what the settings need the whole record
/// for (an error with `--stream on`).
fn decide_stream(args: &Args, why: Option<&str>) -> anyhow::Result<bool> {
    args.stream.decide(&args.data, why.map(String::from), |why| {
        sysid::SysidError::setting(
            sysid::Setting::Other("--stream"),
            "on",
            &format!(
                "a single-input ARX, Hammerstein or output-error model with --horizon 1 and no --out or \
                 --resample, or no --stream; here: {why}"
            ),
        )
    })
}

/// `validate` with the record read in passes (`sysid::stream`).
fn run_streamed(
    args: &Args,
    model: &sysid::Model,
    opts: &sysid::data::CsvOptions,
    inputs: &[&Path],
) -> anyhow::Result<()> {
    let mut src = sysid::data::stream::CsvStream::open(&args.data, opts)?;
    let name = sysid::data::stream::RecordSource::name(&src).to_string();
    // A numerical failure is blamed on the model file's coefficient when one explains it, as the
    // in-memory path does (one more pass gathers the record's sizes, only on that failure).
    let streamed =
        sysid_summary::stream::validation_report(model, &mut src, args.resid_lags, args.score_from)
            .map_err(|e| {
                blame_model(e, model, &args.model, &name, || {
                    sysid::stream::term_sizes(model, &mut src)
                })
            })?;
    let shape = streamed.shape;
    // The name once read: with --rows it says which rows (`file.csv[100..600]`), as in memory.
    let name = sysid::data::stream::RecordSource::name(&src).to_string();
    // The reader's notes, as in memory (audit s27 M-2).
    let notes = src.notes().to_vec();
    sysid::metrics::check_sampling_noted(&name, shape.ts, model.ts(), &notes)?;
    stream_note(&name, streamed.passes, shape.rows, args.stream);
    let mut report = streamed.result;
    report.warnings.extend(super::common::data_notes(&notes));
    let samples = src.checksum().map(|c| Samples::Streamed {
        checksum: c,
        len: shape.rows,
    });
    model_warnings(&mut report, model, &name, shape.rows, opts, samples);
    // The 1-step prediction of `model_output`: the ARX predictor, or for an output-error model the
    // simulation from the estimated initial outputs, as in memory (`ModelOutput::y_pred`; audit s27 H-2).
    let m = &report.metrics.validation;
    let fit_horizon = match model.noise_model() {
        sysid::model::NoiseModel::EquationError => m.fit_pred_percent,
        sysid::model::NoiseModel::OutputError => m.fit_sim_percent,
    };
    let value = report_json(&report, args.horizon, fit_horizon, &notes)?;
    let text = report_text(args, &report, &name, shape.rows, fit_horizon);
    print_report(&text, &[args.json.as_deref(), args.out.as_deref()])?;
    finish(args, report.warnings.len(), &value, None, inputs)
}

/// A numerical failure `e` of `model` (read from `path`) on the record `name` blamed on the model file
/// when one of its coefficients explains it ([`sysid::Model::overflowing_term`] of the record's
/// [`sysid::TermSizes`], gathered by `sizes` only then): the error names the file and the
/// coefficient, not the data (audit s17 L-c: a1 = 1e308 was reported as "values too large? rescale
/// the data"). The one path of `validate` and `validate --stream`. Any other error, or a failure to
/// gather the sizes, returns `e` as it is.
fn blame_model(
    e: sysid::SysidError,
    model: &sysid::Model,
    path: &Path,
    name: &str,
    sizes: impl FnOnce() -> Result<sysid::TermSizes, sysid::SysidError>,
) -> sysid::SysidError {
    if !e.is_numerical() {
        return e;
    }
    match sizes().ok().and_then(|s| model.overflowing_term(&s)) {
        Some(why) => sysid::SysidError::Numerical(format!(
            "{}: the model's {why}: the model file holds an absurd coefficient (hand-edited or \
             damaged?); the record {name} is not to blame",
            path.display()
        )),
        None => e,
    }
}

/// Adds what the model file itself deserves a warning for (a map that breaks its kind's shape, its
/// identification's warnings) to the report, and the record's in-sample warning
/// ([`in_sample_warning`]).
fn model_warnings(
    report: &mut ValidationReport,
    model: &sysid::Model,
    name: &str,
    len: usize,
    opts: &sysid::data::CsvOptions,
    data: Option<Samples<'_>>,
) {
    report
        .warnings
        .extend(in_sample_warning(model.provenance(), name, len, opts, data));
    let said = report.warnings.clone();
    report.warnings.extend(
        sysid::model_file::load_warnings_besides(model, &said)
            .into_iter()
            .map(|w| format!("model: {w}")),
    );
}

/// A record `name` of `len` rows, read with `opts`, that holds the model's own estimation rows in the
/// same columns (`sysid_summary::estimation_rows_warning`) or, read in memory (`data`), the estimation
/// record's samples under another name ([`estimation_record`]; audit s22 M-R2), by its checksum when it
/// was streamed (audit s27 M-2). `provenance`: the model file's identification record (a linear
/// model's or a NARX model's; audit s33 M-1).
fn in_sample_warning(
    provenance: Option<&sysid::model::Provenance>,
    name: &str,
    len: usize,
    opts: &sysid::data::CsvOptions,
    data: Option<Samples<'_>>,
) -> Option<String> {
    let u = opts.input_names();
    let columns = (!opts.no_header).then_some((u.as_slice(), opts.y_col.as_str()));
    sysid_summary::estimation_rows_warning(provenance, name, len, columns).or_else(|| {
        let est = estimation_record(provenance?, opts)?;
        match data? {
            Samples::InMemory(d) => sysid_summary::same_samples_warning("validation", d, &est),
            // A streamed record: the same samples by the pass's checksum (one input).
            Samples::Streamed { checksum, len } => (len == est.len()
                && est.inputs().len() == 1
                && sysid::data::stream::samples_checksum(est.u(), est.y()) == checksum)
                .then(|| sysid_summary::same_samples_words("validation", name, est.name())),
        }
    })
}

/// The model's estimation record, to find a validated record that holds its samples (all of them, or
/// a run of `sysid_summary::MIN_SHARED_SAMPLES`), compared as identify compares its validation record
/// (`sysid_summary::same_samples_warning`; a streamed record: all of them, by checksum): the record the
/// model file names (`identification.record`,
/// its rows and columns) is read again with `opts`' other settings. A copy of the estimation file
/// under another name was validated without a word (audit s22 M-R2). `None` when the file is not
/// there (the path is as identify was given it), is one that validate would
/// stream (`sysid::stream::AUTO_STREAM_BYTES` or more), or cannot be read: then nothing is known.
fn estimation_record(
    p: &sysid::model::Provenance,
    opts: &sysid::data::CsvOptions,
) -> Option<sysid::Dataset> {
    let (file, rows) = sysid_summary::record_rows(&p.record);
    let path = Path::new(file);
    let small = std::fs::metadata(path)
        .is_ok_and(|m| m.is_file() && m.len() < sysid::stream::AUTO_STREAM_BYTES);
    if file == "-" || !small {
        return None;
    }
    let mut est_opts = opts.clone();
    if !est_opts.no_header {
        if !p.u_columns.is_empty() {
            est_opts.u_col = p.u_columns.join(",");
        }
        if let Some(y) = &p.y_column {
            est_opts.y_col = y.clone();
        }
    }
    est_opts.rows = rows.map(|r| sysid::data::RowRange {
        start: Some(r.start),
        end: Some(r.end),
    });
    sysid::data::read_record(path, &est_opts)
        .ok()
        .map(|r| r.data)
}

/// The samples of the record validated, for the comparison with the estimation record's.
#[derive(Clone, Copy)]
enum Samples<'a> {
    /// Read in memory.
    InMemory(&'a sysid::Dataset),
    /// Read in passes: the checksum of the u and y values and the number of samples.
    Streamed { checksum: u64, len: usize },
}

/// Refuses a validation whose simulation, predictions, residuals and `--out` columns would exceed
/// the budget `max_memory`, before any of them is made (audit s23 H-B1): a linear model's and a
/// polynomial NARX model's alike ([`super::common::check_record_memory`]).
fn check_validate_memory(
    data: &sysid::data::Dataset,
    p: usize,
    max_memory: sysid::ls::MemoryBudget,
) -> anyhow::Result<()> {
    super::common::check_record_memory(
        format!("validate on {}", data.name()),
        data.len(),
        p,
        max_memory,
        "--rows A..B, or a coarser sampling: --resample TS",
    )
}
