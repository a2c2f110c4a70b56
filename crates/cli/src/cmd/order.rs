//! `ipa-sysid order`: rank model orders and delays (MATLAB `arxstruc`/`selstruc`) by fit on a selection
//! record, with AIC and FPE beside it; the search itself is `sysid::order::search` (parallel).
//!
//! Honest selection: the ranking never sees the test record. Structures are estimated on the estimation
//! part and ranked by their free-run fit on the selection part (`--selection-rows`, or by default the last
//! `1 − --selection-split` of the estimation record); the chosen structure is then re-estimated on the whole
//! estimation record and its fit on the test record (`--validation`, `--val-rows` or `--split`) is
//! reported separately.

use std::path::{Path, PathBuf};

use report::format::num;
use sysid::model::MAX_ORDER;
use sysid::order::{grid_size, search, Candidate};
use sysid::{Dataset, Identification, Method, ModelKind};

use super::common::{
    check_outputs, parse_rows, print_notes, print_report, progress_bar, same_samples_warning,
    shared_rows_warning, write_outputs, ColumnArgs, FileRows, ValidationArgs,
};
use sysid::data::RowRange;

/// Flags of `order`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Estimation CSV file (header row; columns chosen by --u-col, --y-col, --t-col).
    #[arg(long, value_name = "FILE")]
    pub data: PathBuf,
    #[command(flatten)]
    pub columns: ColumnArgs,
    #[command(flatten)]
    pub val: ValidationArgs,
    /// Orders of A to try: a..b (inclusive) or a single value.
    #[arg(long, default_value = "1..5")]
    pub na: String,
    /// Numbers of B coefficients to try.
    #[arg(long, default_value = "1..3")]
    pub nb: String,
    /// Input delays to try; `auto` estimates the delay first (as `ipa-sysid delay`) and tries it ± 1.
    #[arg(long, default_value = "0..5")]
    pub nk: String,
    /// Rows A..B of the --data file that rank the structures, never used for estimation: the
    /// structures are estimated on the data rows (--rows, default the whole file) without them, so they
    /// lie at the start or the end of the data rows, or outside them. Default: the last part of the
    /// estimation record (see --selection-split).
    #[arg(long, value_name = "A..B", value_parser = parse_rows)]
    pub selection_rows: Option<RowRange>,
    /// Without --selection-rows: estimate on this first fraction of the estimation record, rank on the rest.
    #[arg(long, default_value_t = 2.0 / 3.0, value_name = "F")]
    pub selection_split: f64,
    /// Model structure (`--model` is an older spelling; `--model` names a model file elsewhere). The
    /// default differs from `identify` on purpose: the search is MATLAB's `arxstruc`/`selstruc`, linear
    /// structures that need no two-sided deadzone excitation; `identify` defaults to the paper's model.
    #[arg(
        long = "structure",
        alias = "model",
        value_name = "STRUCTURE",
        value_enum,
        default_value = "arx"
    )]
    pub model: ModelKind,
    /// Estimator. The default differs from `identify` (rls, the paper's) on purpose: least squares is
    /// the closed form for every structure of the grid, which RLS with ρ = 1 converges to.
    #[arg(long, value_enum, default_value = "ls")]
    pub method: Method,
    /// Estimate a constant term c in the linear block.
    #[arg(long)]
    pub offset: bool,
    /// Judge every part around the estimation record's operating point (MATLAB `detrend`): `mean`
    /// subtracts its means ū, ȳ from the estimation, selection and test records alike (what a model
    /// identified with `identify --detrend mean` does); `linear` is refused here (a line fitted to one
    /// part does not extend to another).
    #[arg(long, value_enum, default_value = "none")]
    pub detrend: sysid::detrend::Detrend,
    /// How many ranked structures to print (all go to --json).
    #[arg(long, default_value_t = 15)]
    pub top: usize,
    /// Write the ranking as JSON here (`-` for standard output).
    #[arg(long, value_name = "OUT")]
    pub json: Option<PathBuf>,
    /// Exit with code 1 when the result carries warnings (they are printed either way), without writing
    /// --json (an earlier file there is kept).
    #[arg(long)]
    pub strict: bool,
    #[command(flatten)]
    pub memory: super::common::MemoryArgs,
    /// Structure search over model classes instead of orders of one structure: a list of `arx`,
    /// `hammerstein` (the deadzone) or `hammerstein:KIND` / `KIND` (an input nonlinearity kind of
    /// --nonlinearity), `narxD` (polynomial NARX of degree D), `wiener:KIND[:N]` (a linear block and an
    /// output nonlinearity, e.g. `wiener:polynomial:2`), each tried at every (na, nb, nk) of the
    /// grid and ranked by free-run RMSE on the selection part (docs/models.md).
    #[arg(long, value_name = "CLASS,...", value_delimiter = ',', value_parser = parse_class)]
    pub classes: Vec<sysid::search::Class>,
    #[command(flatten)]
    pub narx: super::identify_narx::NarxArgs,
    /// The ids of the arguments typed on the command line (set by `main`), to refuse the NARX settings
    /// when no NARX class is searched.
    #[arg(skip)]
    pub given: Vec<String>,
}

/// Refuses a NARX setting typed when no `narxD` class is searched: it would be ignored silently
/// (audit s12), as `identify` refuses it without `--structure narx`.
fn check_narx_flags(args: &Args) -> anyhow::Result<()> {
    let narx = args
        .classes
        .iter()
        .any(|c| matches!(c, sysid::search::Class::Narx(_)));
    if narx {
        return Ok(());
    }
    for (id, flag) in super::identify_narx::NARX_FLAGS {
        if args.given.iter().any(|g| g == id) {
            anyhow::bail!(
                "{flag} is a setting of the NARX class search (a narxD class in --classes), which this \
                 search does not run; leave out {flag}"
            );
        }
    }
    Ok(())
}

/// Parses one class of `--classes`.
fn parse_class(text: &str) -> Result<sysid::search::Class, String> {
    text.parse()
}

/// Parses `a..b` (inclusive) or a single value `a`; `flag` names the option in errors.
pub fn parse_range(text: &str, flag: &'static str) -> anyhow::Result<Vec<usize>> {
    let bad = || {
        sysid::SysidError::setting(
            sysid::Setting::Other(flag),
            text,
            &format!("an order a..b (inclusive, a <= b) or a single value, at most {MAX_ORDER}"),
        )
    };
    let t = text.trim();
    let (a, b) = match t.split_once("..") {
        Some((a, b)) => (
            a.trim().parse::<usize>().map_err(|_| bad())?,
            b.trim().parse::<usize>().map_err(|_| bad())?,
        ),
        None => {
            let v = t.parse::<usize>().map_err(|_| bad())?;
            (v, v)
        }
    };
    if a > b || b > MAX_ORDER {
        return Err(bad().into());
    }
    Ok((a..=b).collect())
}

/// The JSON document of `order --json`.
#[derive(Debug, serde::Serialize)]
struct OrderReport<'a> {
    /// The record the structures were estimated on.
    data: String,
    /// The record that ranked them (its fit is each candidate's `fit_validation`).
    selection: String,
    /// The test record, never used for ranking.
    validation: Option<String>,
    ranked_by: &'static str,
    /// The delay estimate behind `--nk auto`.
    #[serde(skip_serializing_if = "Option::is_none")]
    delay: Option<sysid::delay::DelayEstimate>,
    /// The chosen structure, re-estimated on the whole estimation record, on the test record.
    test: Option<TestResult>,
    /// Reasons not to trust the recommendation (always present; empty when all is well).
    warnings: &'a [String],
    candidates: &'a [Candidate],
}

/// The chosen structure's fit on the test record.
#[derive(Debug, serde::Serialize)]
struct TestResult {
    orders: sysid::Orders,
    /// Re-estimated on this record (estimation and selection rows together).
    estimated_on: String,
    data: String,
    /// The test fit the text's headline gives and the ranking's measure: the free-run simulation fit %,
    /// the worse of estimated and measured initial outputs (`sysid::trust::guarded_fit`; audit s21
    /// L-A1: it was the estimated-initial-output one, which the text says not to rank on).
    fit_sim_percent: Option<f64>,
    /// The free-run simulation fit % from estimated initial outputs alone (MATLAB `compare`'s
    /// default; `metrics.fit_sim_percent`).
    fit_sim_estimated_percent: Option<f64>,
    metrics: sysid::metrics::Metrics,
}

/// Runs `order`.
pub fn run(args: Args) -> anyhow::Result<()> {
    check_narx_flags(&args)?;
    let na = parse_range(&args.na, "--na")?;
    let nb = parse_range(&args.nb, "--nb")?;
    let auto_nk = args.nk.trim() == "auto";
    let mut nk = if auto_nk {
        Vec::new()
    } else {
        parse_range(&args.nk, "--nk")?
    };
    // The work is bounded before any record is read (nk auto adds three delays to the grid).
    let structures = sysid::order::grid_size(&na, &nb, if auto_nk { &[0, 1, 2] } else { &nk })
        .saturating_mul(args.classes.len().max(1));
    if structures > sysid::order::MAX_STRUCTURES {
        anyhow::bail!(sysid::SysidError::setting(
            sysid::Setting::Other("--na/--nb/--nk"),
            format!("{} x {} x {}", args.na, args.nb, args.nk),
            &format!(
                "a search of at most {} structures (this one has {structures}{}); narrow the ranges, \
                 e.g. search na and nb first with a fixed nk (`ipa-sysid delay` estimates it)",
                sysid::order::MAX_STRUCTURES,
                if args.classes.is_empty() {
                    String::new()
                } else {
                    format!(", {} classes", args.classes.len())
                }
            )
        ));
    }
    let base = Identification {
        drop_unexcited_branch: true,
        max_memory: args.memory.max_memory,
        ..Identification::default()
    }
    .with_kind(args.model)
    .with_method(args.method)
    .with_offset(args.offset);
    let mut inputs: Vec<&Path> = vec![&args.data];
    inputs.extend(args.val.validation.as_deref());
    check_outputs(&[(&args.json, "--json")], &inputs)?;
    let opts = args.columns.csv_options(&args.memory);
    let records = args.val.records(&args.data, &opts)?;
    let (data, test) = (records.est, records.val);
    let mut notes = records.notes;
    let (fit_part, selection) = selection_parts(&args, &data, &opts, &mut notes)?;
    let (data, test, fit_part, selection) =
        detrended(args.detrend, (data, test, fit_part, selection), &mut notes)?;
    print_notes(&notes);
    let mut warnings = in_sample_warnings(&args, &opts, &data, test.as_ref());
    // The test record is held out unless it shares rows or samples with what was fitted or ranked.
    let test_shares_rows = !warnings.is_empty();
    if !args.classes.is_empty() {
        if auto_nk {
            anyhow::bail!("--classes takes a --nk range, not auto");
        }
        warnings.extend(selection_length_warning(
            &selection,
            largest_k0(&na, &nb, &nk),
        ));
        return super::order_classes::run(
            &args,
            &base,
            (&data, &fit_part, &selection, test.as_ref()),
            (&na, &nb, &nk),
            (&inputs, warnings, &notes),
        );
    }
    let delay = if auto_nk {
        let d = sysid::delay::estimate_delay_with_progress(
            &fit_part,
            2,
            2,
            10,
            &|_| {},
            args.memory.max_memory,
        )?;
        nk = (d.nk.saturating_sub(1)..=d.nk + 1).collect();
        Some(d)
    } else {
        None
    };
    warnings.extend(selection_length_warning(
        &selection,
        largest_k0(&na, &nb, &nk),
    ));
    sysid::order::check_memory(&fit_part, &na, &nb, &nk, &base)?;
    let bar = progress_bar(
        grid_size(&na, &nb, &nk) as u64,
        "{bar:40} {pos}/{len} structures {elapsed}",
    );
    let ranked = search(&fit_part, Some(&selection), &na, &nb, &nk, &base, &|| {
        bar.inc(1)
    });
    bar.finish_and_clear();
    let ranked_by =
        "selection fit % (simulation, the worse of estimated and measured initial outputs); \
                     structures a warning disqualifies (unstable, negative fit, not converged, worse \
                     than the linear start or baseline, nonlinearity not physical) last";
    warnings.extend(sysid::order::search_warnings(&ranked, &na, &nb, &nk));
    for w in delay.iter().flat_map(|d| &d.warnings) {
        warnings.push(format!("--nk auto: {w}"));
    }
    // The chosen structure on the test record, re-estimated on the whole estimation record.
    let chosen = sysid::order::recommended(&ranked);
    if args.detrend == sysid::detrend::Detrend::None {
        warnings.extend(chosen.and_then(|c| {
            sysid::order::offset_hint(
                (&fit_part, Some(&selection)),
                &base,
                (c.orders, c.ranking_fit, None),
                (
                    &format!(
                        "the recommended ({}, {}, {})",
                        c.orders.na, c.orders.nb, c.orders.nk
                    ),
                    "search again with --offset (or --detrend mean)",
                ),
            )
        }));
    }
    if let Some(c) = chosen {
        warnings.extend(c.warnings.iter().map(|w| {
            format!(
                "recommended ({}, {}, {}): {w}",
                c.orders.na, c.orders.nb, c.orders.nk
            )
        }));
    }
    let test_result = match (chosen, &test) {
        (Some(c), Some(t)) => Some(chosen_on_test(c, &base, &data, t, &mut warnings)?),
        _ => None,
    };
    // Without a test record the selection part is the only held-out evidence: the chosen structure's
    // fall from its estimation fit to it is warned by identify's rule (audit s22 M-R1: the gas
    // furnace's (4, 2, 4) fell from 84.4 % to 46.1 % without a word; identify on the same rows warned).
    if let (Some(c), None) = (chosen, &test) {
        warnings.extend(
            sysid::trust::held_out_drop(
                (
                    sysid::warnings::Record::Estimation,
                    c.fit_estimation_guarded,
                ),
                (sysid::warnings::Record::Selection, c.ranking_fit),
            )
            .map(|w| {
                format!(
                    "recommended ({}, {}, {}): {w}",
                    c.orders.na, c.orders.nb, c.orders.nk
                )
            }),
        );
    }
    let mut text = format!(
        "Order search: {} structures ({} model, {} estimator) estimated on {} ({} samples), ranked on \
         {} ({} samples{}) by {ranked_by}, then fewer parameters, then AIC\n",
        ranked.len(),
        base.structure.kind,
        sysid::Estimator::method(&base.estimator),
        fit_part.name(),
        fit_part.len(),
        selection.name(),
        selection.len(),
        if args.selection_rows.is_some() {
            ", never used for estimation"
        } else {
            ""
        }
    );
    if let Some(d) = &delay {
        text.push_str(&format!(
            "--nk auto: estimated delay nk = {} (ARX(2, 2) fits over nk = 0..10), trying nk = {:?}{}\n",
            d.nk,
            nk,
            if d.warnings.is_empty() {
                ""
            } else {
                " (see the warnings below)"
            }
        ));
        for n in &d.notes {
            text.push_str(&format!("--nk auto: note: {n}\n"));
        }
    }
    text.push('\n');
    text.push_str(&candidate_rows(&ranked, args.top));
    let o = |v: Option<f64>| v.map_or_else(|| "n/a".to_string(), num);
    match (&test_result, &test) {
        (Some(t), _) => text.push_str(&format!(
            "\nChosen structure (na, nb, nk) = ({}, {}, {}), re-estimated on {}: test fit {} % (simulation, \
             the worse of estimated and measured initial outputs, as ranked; {} % from estimated ones) \
             on {} ({})\n",
            t.orders.na,
            t.orders.nb,
            t.orders.nk,
            t.estimated_on,
            o(t.fit_sim_percent),
            o(t.fit_sim_estimated_percent),
            t.data,
            if test_shares_rows {
                "NOT held out: it shares rows with the estimation or selection data, see the warnings"
            } else {
                "never used for ranking"
            }
        )),
        (None, Some(_)) => text.push_str("\nNo structure qualifies: no test fit.\n"),
        (None, None) => text.push_str(
            "\nNo test record (--validation, --val-rows or --split): the selection fit of the chosen \
             structure is optimistic; check it on data it has not seen.\n",
        ),
    }
    for w in &warnings {
        text.push_str(&format!("warning: {w}\n"));
    }
    // Nothing could be estimated: an error after the table (which says why for each structure), as
    // identify's on the same data; the --json file is then not written (as montecarlo's).
    let failed = ranked.iter().filter(|c| c.error.is_some()).count();
    let nothing = failed == ranked.len();
    if nothing {
        text.push_str(&format!(
            "Every structure failed to estimate ({failed} of {failed}): nothing could be estimated, \
             no structure is recommended.\n"
        ));
    }
    print_report(&text, &[args.json.as_deref()])?;
    let json_to_stdout = args.json.as_deref().is_some_and(|p| p.as_os_str() == "-");
    if nothing && !json_to_stdout {
        if let Some(path) = &args.json {
            eprintln!(
                "{}: not written: no structure could be estimated (an existing file is left as it was)",
                path.display()
            );
        }
        return Err(nothing_estimated(&ranked, failed));
    }
    // The reader's notes (printed first, as warnings) join the JSON's warnings as identify's do, and
    // count for --strict.
    let warnings: Vec<String> = super::common::data_notes(&notes).chain(warnings).collect();
    let mut json = None;
    if args.json.is_some() {
        let doc = OrderReport {
            warnings: &warnings,
            data: fit_part.name().to_string(),
            selection: selection.name().to_string(),
            validation: test.as_ref().map(|v| v.name().to_string()),
            ranked_by,
            delay,
            test: test_result,
            candidates: &ranked,
        };
        json = Some(super::common::report_json(&doc, true)? + "\n");
    }
    let mut outputs: Vec<(&Path, &[u8], &str)> = Vec::new();
    if let (Some(path), Some(text)) = (&args.json, &json) {
        outputs.push((path, text.as_bytes(), "--json"));
    }
    if nothing {
        // The JSON went to standard output (the report); the failure is the error.
        write_outputs(&outputs, &inputs, false, 0)?;
        return Err(nothing_estimated(&ranked, failed));
    }
    // With --strict and warnings, --json is not written (an earlier file stays) and the exit code is 1.
    write_outputs(&outputs, &inputs, args.strict, warnings.len())
}

/// The error when every one of the `failed` structures of `ranked` failed to estimate: exit 1 when a
/// numerical failure is among them; 2 when the data (or a setting) refused every structure, as
/// `identify` exits on the same record (audit s14 L-j).
fn nothing_estimated(ranked: &[Candidate], failed: usize) -> anyhow::Error {
    let first = ranked.iter().find_map(|c| c.error.as_deref()).unwrap_or("");
    let message = format!(
        "every one of the {failed} structures failed to estimate (the first: {first}); nothing \
         could be estimated from this record"
    );
    if ranked.iter().any(|c| c.error_numerical) {
        sysid::SysidError::Numerical(message).into()
    } else {
        sysid::SysidError::Data(message).into()
    }
}

/// The estimation part and the selection part of the estimation record: `--selection-rows` of the data
/// file, or the `--selection-split` fraction of `data`.
fn selection_parts(
    args: &Args,
    data: &Dataset,
    opts: &sysid::data::CsvOptions,
    notes: &mut Vec<String>,
) -> anyhow::Result<(Dataset, Dataset)> {
    Ok(match &args.selection_rows {
        Some(r) => {
            let sopts = sysid::data::CsvOptions {
                rows: Some(*r),
                rows_flag: "--selection-rows",
                ..opts.clone()
            };
            let sel = sysid::data::read_record(&args.data, &sopts)?;
            notes.extend(sel.notes);
            (estimation_rows(args, data, opts, *r)?, sel.data)
        }
        None => {
            let n = data.len();
            let k = sysid::data::split_rows(n, args.selection_split).map_err(|_| {
                sysid::SysidError::setting(
                    sysid::Setting::Other("--selection-split"),
                    args.selection_split,
                    &format!(
                        "a fraction F with 0 < F < 1 of the {n} estimation rows, leaving rows to rank on"
                    ),
                )
            })?;
            (data.rows(0..k), data.rows(k..n))
        }
    })
}

/// The estimation part when `--selection-rows S` are given: the data rows R (`--rows`, default the whole
/// file) minus S, which must leave one contiguous part (S at the start or the end of R, or outside it).
/// `data` is the record of R, returned as it is when S lies outside R.
fn estimation_rows(
    args: &Args,
    data: &Dataset,
    opts: &sysid::data::CsvOptions,
    s: RowRange,
) -> anyhow::Result<Dataset> {
    let r = args.columns.rows.unwrap_or_default();
    if r.intersection(&s).is_none() {
        return Ok(data.clone());
    }
    // The file's row count resolves open ends (`600..`): the rows before any resampling, without Ts.
    let count = sysid::data::CsvOptions {
        rows: None,
        resample: None,
        ts: Some(1.0),
        ..opts.clone()
    };
    let n = sysid::data::read_record(&args.data, &count)?.data.len();
    let name = args.data.display().to_string();
    let r = r.resolve(n, "--rows", &name)?;
    let s = s.resolve(n, "--selection-rows", &name)?;
    let before = r.start..s.start.max(r.start);
    let after = s.end.min(r.end)..r.end;
    let part = match (before.is_empty(), after.is_empty()) {
        (false, true) => before,
        (true, false) => after,
        (true, true) => anyhow::bail!(
            "--selection-rows {}..{} cover every estimation row ({}..{} of {name}): no row is left to \
             estimate on; pass --rows with the estimation rows",
            s.start,
            s.end,
            r.start,
            r.end
        ),
        (false, false) => anyhow::bail!(
            "--selection-rows {}..{} lie inside the estimation rows {}..{} of {name} and would cut them in \
             two records; the selection rows are never used for estimation, so choose selection rows at \
             the start or the end of the data rows, or pass --rows with the estimation rows (e.g. --rows \
             {}..{})",
            s.start,
            s.end,
            r.start,
            r.end,
            r.start,
            s.start
        ),
    };
    let eopts = sysid::data::CsvOptions {
        rows: Some(RowRange {
            start: Some(part.start),
            end: Some(part.end),
        }),
        ..opts.clone()
    };
    Ok(sysid::data::read_record(&args.data, &eopts)?.data)
}

/// The most initial samples k0 = max(na, nk + nb − 1) of a structure of the grid: the free-run
/// simulation of the selection part starts from its first k0 samples and compares the rest.
fn largest_k0(na: &[usize], nb: &[usize], nk: &[usize]) -> usize {
    let max = |v: &[usize]| v.iter().copied().max().unwrap_or(0);
    max(na).max((max(nk) + max(nb)).saturating_sub(1))
}

/// How many times the grid's largest k0 the selection part should hold before its fits rank anything.
const SELECTION_K0_FACTOR: usize = 5;

/// A warning when the selection part holds fewer than [`SELECTION_K0_FACTOR`] times the grid's largest
/// k0 samples: the ranking then rests on a handful of compared samples (none for the structures whose k0
/// reaches the part's length).
fn selection_length_warning(selection: &Dataset, k0: usize) -> Option<String> {
    let n = selection.len();
    (n < SELECTION_K0_FACTOR * k0).then(|| {
        format!(
            "the selection part {} holds only {n} samples, fewer than {SELECTION_K0_FACTOR} times the \
             grid's largest k0 = {k0} (k0 = max(na, nk + nb - 1), the initial samples a simulation \
             starts from): the ranking rests on {} compared samples or fewer and may pick by chance; \
             choose more selection rows",
            selection.name(),
            n.saturating_sub(k0)
        )
    })
}

/// Warnings (audit s11 V1) when the test record holds rows the chosen structure was estimated on
/// (`data`, the `--rows` of the file) or ranked on (`--selection-rows`), or the very samples of `data`.
fn in_sample_warnings(
    args: &Args,
    opts: &sysid::data::CsvOptions,
    data: &Dataset,
    test: Option<&Dataset>,
) -> Vec<String> {
    let Some(t) = test else {
        return Vec::new();
    };
    let Some((path, vopts)) = args.val.validation_source(&args.data, opts) else {
        return Vec::new(); // --split: the test rows follow the estimation rows
    };
    let test_rows = FileRows {
        file: path,
        rows: vopts.rows,
        columns: (&vopts.u_col, &vopts.y_col),
    };
    let estimation = FileRows {
        file: &args.data,
        rows: args.columns.rows,
        columns: (&opts.u_col, &opts.y_col),
    };
    let mut w: Vec<String> = shared_rows_warning("test", test_rows, "estimation", estimation)
        .into_iter()
        .collect();
    if w.is_empty() {
        w.extend(same_samples_warning("test", t, data));
    }
    if let Some(rows) = args.selection_rows {
        let selection = FileRows {
            file: &args.data,
            rows: Some(rows),
            columns: estimation.columns,
        };
        w.extend(shared_rows_warning(
            "test",
            test_rows,
            "selection",
            selection,
        ));
    }
    w
}

/// The ranking table: a header and the first `top` candidates.
fn candidate_rows(ranked: &[Candidate], top: usize) -> String {
    let mut text = String::new();
    text.push_str(&format!(
        "{:>4} {:>3} {:>3} {:>3} {:>4} {:>12} {:>12} {:>12} {:>12} {:>12} {:>10}\n",
        "rank",
        "na",
        "nb",
        "nk",
        "p",
        "fit est %",
        "fit sel %",
        "ranked on %",
        "AIC",
        "FPE",
        "stable"
    ));
    let o = |v: Option<f64>| v.map_or_else(|| "n/a".to_string(), num);
    for (i, c) in ranked.iter().take(top).enumerate() {
        text.push_str(&format!(
            "{:>4} {:>3} {:>3} {:>3} {:>4} {:>12} {:>12} {:>12} {:>12} {:>12} {:>10}{}\n",
            i + 1,
            c.orders.na,
            c.orders.nb,
            c.orders.nk,
            c.p,
            o(c.fit_estimation),
            o(c.fit_validation),
            o(c.ranking_fit()),
            o(c.aic),
            o(c.fpe),
            // The stability verdict (`Model::stability`): an integrator or a pole on the circle is
            // neither "yes" nor "no".
            match c.stability.as_str() {
                "integrator" => "integrator",
                "on_circle" => "on circle",
                _ if c.stable => "yes",
                _ => "no",
            },
            c.error
                .as_ref()
                .map(|e| format!("  ({e})"))
                .unwrap_or_default()
        ));
    }
    text
}

/// The four parts of `order`: estimation record, test record, estimation part, selection part.
type Parts = (Dataset, Option<Dataset>, Dataset, Dataset);

/// The parts around the estimation record's operating point (`--detrend mean`), with a note saying so;
/// unchanged for `none`; `linear` refused.
fn detrended(
    detrend: sysid::detrend::Detrend,
    (data, test, fit_part, selection): Parts,
    notes: &mut Vec<String>,
) -> anyhow::Result<Parts> {
    Ok(match detrend {
        sysid::detrend::Detrend::None => (data, test, fit_part, selection),
        sysid::detrend::Detrend::Linear => anyhow::bail!(sysid::SysidError::setting(
            sysid::Setting::Other("--detrend"),
            "linear",
            "none or mean for order (a line fitted to the estimation part does not extend to the \
             selection and test parts); detrend the file first, or use identify --detrend linear",
        )),
        sysid::detrend::Detrend::Mean => {
            let (_, op) = sysid::detrend::detrend(&data, sysid::detrend::Detrend::Mean);
            match op {
                Some(op) => {
                    notes.push(format!(
                        "--detrend mean: every part minus the estimation record's means \
                         (u0 = {:?}, y0 = {})",
                        op.u, op.y
                    ));
                    (
                        op.remove_from(&data),
                        test.map(|t| op.remove_from(&t)),
                        op.remove_from(&fit_part),
                        op.remove_from(&selection),
                    )
                }
                None => (data, test, fit_part, selection),
            }
        }
    })
}

/// The warnings of a model `fit` (identified by `id` on `data`) on the test record `t` (its metrics
/// `m`), each prefixed "test record: ": a negative or diverging simulation, an initial state that
/// flatters the fit, a fit far below the linear least-squares baseline. Shared by `order` and `order
/// --classes`.
pub(super) fn test_record_warnings(
    fit: &sysid::Fitted,
    id: &Identification,
    data: &Dataset,
    t: &Dataset,
    m: &sysid::metrics::Metrics,
) -> Vec<String> {
    let record = sysid::warnings::Record::Test;
    sysid::trust::metric_warnings(record, m)
        .into_iter()
        .chain(sysid::trust::baseline_warning(
            record,
            fit,
            id,
            std::slice::from_ref(data),
            t,
            m,
        ))
        .map(|w| test_record_words(&w))
        .collect()
}

/// A warning about the test record, in words.
pub(super) fn test_record_words(w: &impl std::fmt::Display) -> String {
    format!("test record: {w}")
}

/// The chosen structure `c` re-estimated on the whole estimation record `data` and judged on the test
/// record `t` (never used for ranking), with the test record's warnings added to `warnings`.
fn chosen_on_test(
    c: &Candidate,
    base: &Identification,
    data: &Dataset,
    t: &Dataset,
    warnings: &mut Vec<String>,
) -> anyhow::Result<TestResult> {
    let mut id = base.clone();
    id.structure.orders = c.orders;
    let fit = sysid::estimate::identify(data, &id)?;
    let m = sysid::metrics::metrics(&fit.model, t)?;
    warnings.extend(test_record_warnings(&fit, &id, data, t, &m));
    // The test fit far below the selection fit that chose the structure (audit s21 M-A1: the gas
    // furnace's 94.8 % on the selection part, 53.3 % on the test record).
    let guarded = sysid::trust::guarded_fit(&m);
    warnings.extend(
        sysid::trust::held_out_drop(
            (sysid::warnings::Record::Selection, c.ranking_fit),
            (sysid::warnings::Record::Test, guarded),
        )
        .map(|w| test_record_words(&w)),
    );
    Ok(TestResult {
        orders: c.orders,
        estimated_on: data.name().to_string(),
        data: t.name().to_string(),
        fit_sim_percent: guarded,
        fit_sim_estimated_percent: m.fit_sim_percent,
        metrics: m,
    })
}
