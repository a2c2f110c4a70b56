//! Flags and output helpers shared by several subcommands.

use std::path::{Path, PathBuf};

use sysid::data::{CsvOptions, Record, RowRange, TimeUnit};

/// Parses `--rows A..B`.
pub fn parse_rows(text: &str) -> Result<RowRange, String> {
    text.parse::<RowRange>().map_err(|_| {
        "expected A..B: 0-based data rows, B excluded (A.. and ..B allowed), e.g. 0..500".into()
    })
}

/// Parses `--resid-lags M`: at least one lag (M = 0 left the residual analysis "not available"
/// without an error; audit s13 L3).
pub fn parse_lags(text: &str) -> Result<usize, String> {
    let max = sysid::residuals::MAX_LAG;
    match text.trim().parse::<usize>() {
        Ok(m) if (1..=max).contains(&m) => Ok(m),
        _ => Err(format!("expected a whole number of lags in 1..={max}")),
    }
}

/// Parses `--max-memory GIB` ([`sysid::ls::MemoryBudget`]): a size in GiB, more than 0 and at most
/// 1024.
pub fn parse_max_memory(text: &str) -> Result<sysid::ls::MemoryBudget, String> {
    text.parse::<sysid::ls::MemoryBudget>()
        .map_err(|e| match e {
            sysid::SysidError::Setting { expected, .. } => format!("expected {expected}"),
            e => e.to_string(),
        })
}

/// `--max-memory GIB`: the memory budget of one estimation (docs/reliability.md, "Resource bounds").
#[derive(Debug, Clone, Copy, clap::Args)]
pub struct MemoryArgs {
    /// The most memory one run's large buffers may take (an estimation's matrices; a simulated or
    /// read record and its copies), in GiB (2^30 bytes; more than 0, at most 1024). A run that would
    /// need more is refused before anything is allocated, with the rows or samples that would fit;
    /// raise it on a machine that has the memory.
    #[arg(long, value_name = "GIB", default_value = "4", value_parser = parse_max_memory)]
    pub max_memory: sysid::ls::MemoryBudget,
}

pub use sysid::ls::RECORD_NUMBERS_PER_SAMPLE;

/// Refuses a run of a model with `p` parameters (0: a physics plant) over a record of `rows` samples
/// (`what` names it)
/// whose [`RECORD_NUMBERS_PER_SAMPLE`] numbers per sample would exceed `max_memory`, before any of
/// them is made. `shorter` says how to run on fewer samples (`--rows A..B`, `--samples N`). The words
/// are a record's, not an estimation's (no regression rows, no orders to lower).
pub fn check_record_memory(
    what: String,
    rows: usize,
    p: usize,
    max_memory: sysid::ls::MemoryBudget,
    shorter: &str,
) -> anyhow::Result<()> {
    let Err((bytes, fit)) = sysid::ls::record_budget(rows, 1, max_memory) else {
        return Ok(());
    };
    // p = 0: a physics plant's run (its states, the record's columns and the CSV text of them).
    let (of, held) = if p > 0 {
        (
            format!(" (model of {p} parameters)"),
            "the record, its simulation, predictions, residuals and their copies",
        )
    } else {
        (
            String::new(),
            "the plant's states, the record's columns and their text",
        )
    };
    anyhow::bail!(sysid::SysidError::Data(format!(
        "{}: a record of {rows} samples{of} needs about {} GB ({} numbers of 8 bytes per sample: \
         {held}), more than the budget of {max_memory} GiB ({} GB, --max-memory); use at most {fit} samples \
         ({shorter}), or raise --max-memory if this machine has the memory",
        what,
        sysid::ls::format_gb(bytes),
        RECORD_NUMBERS_PER_SAMPLE,
        sysid::ls::format_gb(max_memory.bytes()),
    )))
}

/// Which columns of a CSV file hold the data, and its sampling period.
#[derive(Debug, Clone, clap::Args)]
pub struct ColumnArgs {
    /// Name of the input column u (with --no-header: its position, 1-based). identify and validate take
    /// several inputs as a list (u1,u2): one B polynomial (and deadzone) per input.
    #[arg(long, default_value = "u", value_name = "NAME")]
    pub u_col: String,
    /// Name of the output column y (with --no-header: its position, 1-based).
    #[arg(long, default_value = "y", value_name = "NAME")]
    pub y_col: String,
    /// Name of the time column (gives Ts when --ts is not passed; must be uniform and increasing).
    #[arg(long, default_value = "t", value_name = "NAME")]
    pub t_col: String,
    /// Sampling period Ts in seconds (overrides the time column).
    #[arg(long, value_name = "SECONDS")]
    pub ts: Option<f64>,
    /// The file has no header row: columns are named by position, 1-based (--u-col 2 --y-col 5 --t-col 1).
    #[arg(long)]
    pub no_header: bool,
    /// Use only data rows A..B (0-based, B excluded; A.. and ..B allowed), e.g. --rows 0..500.
    #[arg(long, value_name = "A..B", value_parser = parse_rows)]
    pub rows: Option<RowRange>,
    /// Unit of the time column (Ts and --ts are always in seconds).
    #[arg(long, value_enum, default_value = "s")]
    pub time_unit: TimeUnit,
    /// Interpolate a non-uniform record onto a uniform grid with this Ts in seconds (linear; a warning
    /// says how non-uniform it was).
    #[arg(long, value_name = "SECONDS", conflicts_with = "ts")]
    pub resample: Option<f64>,
}

impl ColumnArgs {
    /// The reader options for these flags, the reader's own bytes (a `.mat` file's inflated
    /// variables) bounded by the budget of `--max-memory`, checked before they are allocated. The one
    /// constructor of every command that reads a record (`identify`, `validate`, `order`, `delay`,
    /// `calibrate`), so that the budget holds for all of them (session 26).
    pub fn csv_options(&self, memory: &MemoryArgs) -> CsvOptions {
        CsvOptions {
            u_col: self.u_col.clone(),
            y_col: self.y_col.clone(),
            t_col: self.t_col.clone(),
            ts: self.ts,
            fallback_ts: None,
            no_header: self.no_header,
            rows: self.rows,
            rows_flag: "--rows",
            time_unit: self.time_unit,
            resample: self.resample,
            max_read_bytes: Some(memory.max_memory.bytes()),
            // The command sets it where it would read the record in passes (identify, validate).
            in_passes: None,
        }
    }
}

/// `--stream`: read a record in passes with bounded memory (docs/data.md, "Long records").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum StreamMode {
    /// Stream a CSV file of 64 MiB or more (`sysid::stream::AUTO_STREAM_BYTES`) when the command's
    /// settings allow it; otherwise read the record into memory.
    #[default]
    Auto,
    /// Always stream; settings that need the whole record are an error.
    On,
    /// Never stream.
    Off,
}

impl StreamMode {
    /// Whether to stream `data`: `why_not` is the reason the settings cannot be streamed, if any
    /// (an error with `--stream on`); `refused` makes that error.
    pub fn decide(
        self,
        data: &Path,
        why_not: Option<String>,
        refused: impl FnOnce(&str) -> sysid::SysidError,
    ) -> anyhow::Result<bool> {
        match self {
            StreamMode::Off => Ok(false),
            StreamMode::On => match why_not {
                Some(why) => Err(refused(&why).into()),
                None => Ok(true),
            },
            StreamMode::Auto => {
                let large = std::fs::metadata(data)
                    .is_ok_and(|m| m.is_file() && m.len() >= sysid::stream::AUTO_STREAM_BYTES);
                let csv = !sysid_core::data::mat::has_mat_name(data);
                if let (true, true, Some(why)) = (large, csv, &why_not) {
                    // A large file read whole is said, with the reason (audit s27 L-9, M-1).
                    eprintln!(
                        "note: {} is {} MiB or more but is read into memory: {why}",
                        data.display(),
                        sysid::stream::AUTO_STREAM_BYTES >> 20
                    );
                }
                Ok(large && csv && why_not.is_none())
            }
        }
    }
}

/// Says on standard error that `name` (of `rows` rows) was read in `passes` passes.
pub fn stream_note(name: &str, passes: usize, rows: usize, mode: StreamMode) {
    eprintln!(
        "note: {name} was read in {passes} passes ({rows} rows; memory does not grow with the record{})",
        if mode == StreamMode::On {
            ""
        } else {
            "; streamed automatically for a large file"
        }
    );
}

pub use sysid_core::data::report_json;

/// Whether any of a command's outputs is `-` (standard output).
pub fn any_to_stdout(outputs: &[Option<&Path>]) -> bool {
    outputs.iter().flatten().any(|p| p.as_os_str() == "-")
}

/// Prints a command's text report: on standard error when one of its `outputs` (`--json`, `--out`,
/// `--save-model`) goes to standard output (`-`), so that standard output carries that one parseable
/// document alone, else on standard output ([`print_stdout`]: a failed write is an error, not a panic).
pub fn print_report(text: &str, outputs: &[Option<&Path>]) -> anyhow::Result<()> {
    if any_to_stdout(outputs) {
        eprint!("{text}");
        Ok(())
    } else {
        print_stdout(text)
    }
}

/// Writes `text` to standard output and flushes it. A write that fails (standard output on a full
/// disk, `>/dev/full`, a closed pipe) is an error naming standard output, so the command exits
/// non-zero with one `error:` line; `print!` would panic with a backtrace.
pub fn print_stdout(text: &str) -> anyhow::Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes())
        .and_then(|()| out.flush())
        .map_err(|e| {
            // The operating system's error stays in the chain (a broken pipe ends the run quietly: main.rs).
            let text = format!("cannot write the report to standard output: {e}");
            anyhow::Error::new(e).context(text)
        })
}

/// Refuses more than one output to standard output (`-`): two documents in one stream parse as
/// neither. `outputs` pairs each path with its flag.
pub fn refuse_two_stdout(outputs: &[(Option<&Path>, &str)]) -> anyhow::Result<()> {
    let flags: Vec<&str> = outputs
        .iter()
        .filter(|(p, _)| p.is_some_and(|p| p.as_os_str() == "-"))
        .map(|(_, f)| *f)
        .collect();
    if let [first, second, ..] = flags.as_slice() {
        anyhow::bail!(sysid_io::OutputError::Refused {
            flag: second.to_string(),
            path: PathBuf::from("-"),
            expected: format!(
                "a file: {first} already writes to standard output, and one stream holds one document"
            ),
        });
    }
    Ok(())
}

/// Prints the reader's warnings on standard error.
pub fn print_notes(notes: &[String]) {
    for n in notes {
        eprintln!("warning: {n}");
    }
}

/// Writes `content` to `path` ([`sysid_io::write_atomic`]: atomically, or straight into a device or FIFO,
/// or to standard output when `path` is `-`). Refuses to write over
/// any of `inputs`; `flag` names the option in messages.
pub fn write_output(
    path: &Path,
    content: &[u8],
    inputs: &[&Path],
    flag: &str,
) -> anyhow::Result<()> {
    sysid_io::refuse_overwrite_input(path, inputs, flag)?;
    print_replaced(&write_all(&[(path, content)])?);
    Ok(())
}

/// [`sysid_io::write_all_atomic`], saying on standard error, once, when a FIFO output has had no reader
/// for a second (audit s30: `--out FIFO` with nobody reading it waited without a word, as a Unix tool's
/// output does; a signal still ends the process).
fn write_all(outputs: &[(&Path, &[u8])]) -> Result<Vec<PathBuf>, sysid_io::OutputError> {
    let start = std::time::Instant::now();
    let mut said = false;
    let mut note = || {
        if !said && start.elapsed() >= std::time::Duration::from_secs(1) {
            said = true;
            eprintln!(
                "note: waiting for a reader of a FIFO output (it is written when one opens it; \
                 Ctrl-C stops)"
            );
        }
        Ok(())
    };
    sysid_io::write_all_atomic_waiting(outputs, sysid_io::forced(), Some(&mut note))
}

/// Says which existing files a write replaced ([`sysid_io::write_all_atomic`]: only by the same kind of
/// file, or with `--force`), or which folder a folder output replaced ([`sysid_io::write_folder`]), so
/// that a replaced file is never a surprise.
pub fn print_replaced(replaced: &[PathBuf]) {
    for p in replaced {
        eprintln!(
            "replaced {}",
            sysid_core::format::visible(&p.display().to_string())
        );
    }
}

/// Writes the outputs of one run together ([`sysid_io::write_all_atomic`]: a failure of any leaves
/// every existing one as it was), refusing to write over any of `inputs`; each output is (path,
/// content, flag). With `--strict` and `warnings` > 0 the files are not written — the run's result is
/// not to be trusted, so an earlier output (a good model a script relies on) must not be replaced by
/// it (audit s14 H-a) — and the error says so (exit 1); what goes to standard output (`-`) is the
/// report and is still written.
pub fn write_outputs(
    outputs: &[(&Path, &[u8], &str)],
    inputs: &[&Path],
    strict: bool,
    warnings: usize,
) -> anyhow::Result<()> {
    for (path, _, flag) in outputs {
        sysid_io::refuse_overwrite_input(path, inputs, flag)?;
    }
    let refused = strict && warnings > 0;
    let written: Vec<(&Path, &[u8])> = outputs
        .iter()
        .filter(|(p, _, _)| !refused || p.as_os_str() == "-")
        .map(|(p, b, _)| (*p, *b))
        .collect();
    print_replaced(&write_all(&written)?);
    if refused {
        let kept: Vec<String> = outputs
            .iter()
            .filter(|(p, _, _)| p.as_os_str() != "-")
            .map(|(p, _, flag)| format!("{flag} {}", p.display()))
            .collect();
        return Err(crate::exit::StrictWarnings {
            warnings,
            not_written: kept,
        }
        .into());
    }
    Ok(())
}

/// Checks before any work that every output path can be written (its folder exists, it is not a folder),
/// names none of the inputs, that no two outputs are the same file, and that at most one is `-`.
pub fn check_outputs(outputs: &[(&Option<PathBuf>, &str)], inputs: &[&Path]) -> anyhow::Result<()> {
    let all: Vec<(Option<&Path>, &str)> = outputs.iter().map(|(p, f)| (p.as_deref(), *f)).collect();
    refuse_two_stdout(&all)?;
    let files: Vec<(&Path, &str)> = outputs
        .iter()
        .filter_map(|(out, flag)| out.as_deref().map(|p| (p, *flag)))
        .filter(|(p, _)| p.as_os_str() != "-")
        .collect();
    for (i, (p, flag)) in files.iter().enumerate() {
        sysid_io::check_writable(p, flag)?;
        sysid_io::refuse_overwrite_input(p, inputs, flag)?;
        for (q, other) in &files[..i] {
            if p == q || target(p) == target(q) {
                anyhow::bail!(sysid_io::OutputError::Refused {
                    flag: flag.to_string(),
                    path: p.to_path_buf(),
                    expected: format!("a path different from {other}"),
                });
            }
        }
    }
    Ok(())
}

/// Where `p` will be written: its folder resolved (links, `.`), then its file name.
fn target(p: &Path) -> Option<PathBuf> {
    let dir = match p.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    Some(std::fs::canonicalize(dir).ok()?.join(p.file_name()?))
}

/// A separate validation record (`--validation FILE`) and its column names.
#[derive(Debug, Clone, clap::Args)]
pub struct ValidationArgs {
    /// Separate record to validate on (CSV or MATLAB .mat, read as --data is).
    #[arg(long, value_name = "FILE")]
    pub validation: Option<PathBuf>,
    /// Input column of the validation file (default: --u-col).
    #[arg(long, value_name = "NAME")]
    pub val_u_col: Option<String>,
    /// Output column of the validation file (default: --y-col).
    #[arg(long, value_name = "NAME")]
    pub val_y_col: Option<String>,
    /// Validation rows A..B (0-based, B excluded) of --validation FILE, or of the --data file itself.
    #[arg(long, value_name = "A..B", value_parser = parse_rows)]
    pub val_rows: Option<RowRange>,
    /// Estimate on the first fraction F of the (--rows) record and validate on the rest (0 < F < 1).
    #[arg(long, value_name = "F", conflicts_with_all = ["validation", "val_rows"])]
    pub split: Option<f64>,
}

/// An estimation record and its optional validation record, with the reader's warnings.
pub struct Records {
    /// The estimation record.
    pub est: sysid::Dataset,
    /// The validation record, if any.
    pub val: Option<sysid::Dataset>,
    /// Reader warnings (resampling) of both.
    pub notes: Vec<String>,
}

impl ValidationArgs {
    /// Reads the validation record, if any, with the estimation file's options except for the columns
    /// named by `--val-u-col` / `--val-y-col` (default: the estimation column names) and the rows
    /// (`--val-rows`, default all). Without `--validation`, `--val-rows` selects rows of `data`.
    pub fn read_from(&self, data: &Path, opts: &CsvOptions) -> anyhow::Result<Option<Record>> {
        match self.validation_source(data, opts) {
            Some((path, vopts)) => Ok(Some(sysid::data::read_record(path, &vopts)?)),
            None => Ok(None),
        }
    }

    /// The file and reader options of the validation record (see [`ValidationArgs::read_from`]), if
    /// any; `--split` is not among them.
    pub fn validation_source<'a>(
        &'a self,
        data: &'a Path,
        opts: &CsvOptions,
    ) -> Option<(&'a Path, CsvOptions)> {
        let path = match (&self.validation, &self.val_rows) {
            (Some(p), _) => p.as_path(),
            (None, Some(_)) => data,
            (None, None) => return None,
        };
        let vopts = CsvOptions {
            u_col: self.val_u_col.clone().unwrap_or_else(|| opts.u_col.clone()),
            y_col: self.val_y_col.clone().unwrap_or_else(|| opts.y_col.clone()),
            rows: self.val_rows,
            rows_flag: "--val-rows",
            ..opts.clone()
        };
        Some((path, vopts))
    }

    /// Reads the validation record of `--validation` (rows `--val-rows`), if any (batch mode, merged
    /// records). With `est_ts` (s, the estimation records' Ts) a record at another Ts is refused as
    /// [`ValidationArgs::records`] refuses it, with its reader's `--time-unit ms` hint.
    pub fn read(
        &self,
        opts: &CsvOptions,
        est_ts: Option<f64>,
    ) -> anyhow::Result<Option<sysid::Dataset>> {
        let Some(p) = &self.validation else {
            return Ok(None);
        };
        let Some(v) = self.read_from(p, opts)? else {
            return Ok(None);
        };
        if let Some(ts) = est_ts {
            sysid::metrics::check_sampling_noted(v.data.name(), v.data.ts(), ts, &v.notes)?;
        }
        Ok(Some(v.data))
    }

    /// The estimation record of `data` (its `--rows`) and the validation record: `--split F` of the
    /// estimation rows, `--validation FILE` (its `--val-rows`), or `--val-rows` of `data`.
    pub fn records(&self, data: &Path, opts: &CsvOptions) -> anyhow::Result<Records> {
        let est = sysid::data::read_record(data, opts)?;
        let mut notes = est.notes;
        if let Some(f) = self.split {
            let n = est.data.len();
            let k = sysid::data::split_rows(n, f)?;
            return Ok(Records {
                val: Some(est.data.rows(k..n)),
                est: est.data.rows(0..k),
                notes,
            });
        }
        let val = match self.read_from(data, opts)? {
            Some(v) => {
                // A validation record at another Ts than the estimation record's (the model's) is
                // refused here, with the reader's --time-unit ms hint when its time column looks like
                // milliseconds, as `validate` refuses it (audit s34 L-8).
                sysid::metrics::check_sampling_noted(
                    v.data.name(),
                    v.data.ts(),
                    est.data.ts(),
                    &v.notes,
                )?;
                notes.extend(v.notes);
                Some(v.data)
            }
            None => None,
        };
        Ok(Records {
            est: est.data,
            val,
            notes,
        })
    }
}

/// Rows and columns of one file: a record as the reader selected it (`rows` `None` = every row).
#[derive(Debug, Clone, Copy)]
pub struct FileRows<'a> {
    /// The file.
    pub file: &'a Path,
    /// Its rows (`--rows`, `--val-rows`, `--selection-rows`).
    pub rows: Option<RowRange>,
    /// The input and output columns read (`--u-col`, `--y-col`; `--val-u-col`, `--val-y-col`).
    pub columns: (&'a str, &'a str),
}

/// Whether two paths name the same file (compared after resolving links), or are the same path.
pub fn same_file(a: &Path, b: &Path) -> bool {
    a == b
        || matches!(
            (std::fs::canonicalize(a), std::fs::canonicalize(b)),
            (Ok(x), Ok(y)) if x == y
        )
}

/// A warning (audit s11 V1) when the `what` record ("validation", "test") holds rows of the file the
/// estimation read (`est`, called `est_what`) in the same columns: its fit is then in-sample, not held
/// out. `None` when the files differ, the rows are disjoint, or other columns are read (the cascaded
/// tanks' file holds its estimation and validation experiments side by side: uEst/yEst, uVal/yVal,
/// audit s12 F1).
pub fn shared_rows_warning(
    what: &str,
    test: FileRows,
    est_what: &str,
    est: FileRows,
) -> Option<String> {
    if test.columns != est.columns || !same_file(test.file, est.file) {
        return None;
    }
    let all = RowRange::default();
    let (t, e) = (test.rows.unwrap_or(all), est.rows.unwrap_or(all));
    let shared = t.intersection(&e)?;
    let rows = if shared == all {
        format!("every row of {} is", test.file.display())
    } else {
        format!("rows {shared} of {} are", test.file.display())
    };
    Some(if shared == t {
        let is = if t == e { "is" } else { "is part of" };
        format!(
            "the {what} record {is} the {est_what} data ({rows} in both): its fit is in-sample, not \
             held out"
        )
    } else {
        format!(
            "the {what} record overlaps the {est_what} data ({rows} in both): its fit is partly in-sample"
        )
    })
}

/// Fraction of samples k ≥ 1 with x(k) = x(k − 1) (0 for fewer than 2 samples).
fn held_fraction(x: &[f64]) -> f64 {
    let n = x.len().saturating_sub(1);
    if n == 0 {
        return 0.0;
    }
    x.windows(2).filter(|w| w[0] == w[1]).count() as f64 / n as f64
}

/// A hint, given beside the warnings of a result that already has some, when the columns look swapped:
/// the output held at the same value in at least 80 % of the samples (as a command held in levels)
/// while the single input changes in more than half of them (as a measurement). The README's record
/// read with u and y swapped fitted 1.55 % with warnings that never named the columns (audits s10-s12);
/// no output column of the records in ../shared/data is held in more than 14 % of its samples.
pub fn swapped_columns_hint(d: &sysid::Dataset) -> Option<String> {
    let [u] = d.input_signals()[..] else {
        return None;
    };
    let (held_y, held_u) = (held_fraction(d.y()), held_fraction(u));
    (held_y >= 0.8 && held_u < 0.5).then(|| {
        format!(
            "the output column is held at the same value in {:.0} % of the samples (like a command held in \
             levels) while the input changes in {:.0} % of them (like a measurement): are --u-col and \
             --y-col swapped?",
            100.0 * held_y,
            100.0 * (1.0 - held_u)
        )
    })
}

pub use sysid_summary::{same_samples, same_samples_warning};

/// A progress bar of `len` steps on standard error with the template `template` (indicatif syntax),
/// hidden when standard error is not a terminal (pipes, CI logs).
pub fn progress_bar(len: u64, template: &str) -> indicatif::ProgressBar {
    use std::io::IsTerminal;
    if !std::io::stderr().is_terminal() {
        return indicatif::ProgressBar::hidden();
    }
    let bar = indicatif::ProgressBar::new(len);
    if let Ok(style) = indicatif::ProgressStyle::with_template(template) {
        bar.set_style(style.progress_chars("=> "));
    }
    bar
}

/// The reader's notes (a resampled gap, a --ts that contradicts the time column, …) as entries of a
/// report's `warnings` list, prefixed `data: ` — one wording for identify (one file, a folder, NARX),
/// validate and order.
pub(super) fn data_notes(notes: &[String]) -> impl Iterator<Item = String> + '_ {
    notes.iter().map(|n| format!("data: {n}"))
}

/// An estimation error after the reader's `notes`, printed first as warnings (`data: …`): a failing
/// estimation never reaches its report, and a note (a value 1e6 times every other of its column, at its
/// line and column) is often its cause (audit s35 M-3: a y of 1e200 at line 101 ended in "least squares
/// produced a non-finite estimate" with the note that names it lost). One path for identify in memory
/// and `--stream on`.
pub(super) fn notes_before(notes: &[String]) -> impl Fn(sysid::SysidError) -> anyhow::Error + '_ {
    move |e| {
        for n in data_notes(notes) {
            eprintln!("warning: {n}");
        }
        e.into()
    }
}
