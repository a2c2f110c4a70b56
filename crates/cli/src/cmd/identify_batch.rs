//! `ipa-sysid identify --data a.csv b.csv …` or `--data DIR`: many records identified in parallel
//! (rayon), one JSON line per file — the single-file `--json` object plus a `"file"` key, or
//! `{"file": …, "error": …}` for a file that fails — in the order the files were given (a folder's
//! `*.csv` and `*.mat` records sorted by name, each read as `--data FILE` reads it). A progress bar goes to standard error when it is a terminal. Every file
//! is processed; the exit status is non-zero when any failed. A folder's record entries that are not
//! regular files (a FIFO, a device, a folder, a broken link) are not opened: a note names them, and
//! each has a line `{"file": …, "skipped": …}` after the others.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use rayon::prelude::*;
use serde::Serialize;
use sysid::{identify, Identification};
use sysid::{Dataset, SysidError};
use sysid_core::format::visible;
use sysid_summary::IdentifyReport;

use super::common::{check_outputs, progress_bar, write_output};
use super::identify::Args;

/// True when `--data` asks for batch mode: more than one path, or a folder.
pub fn is_batch(paths: &[PathBuf]) -> bool {
    paths.len() > 1 || paths.iter().any(|p| p.is_dir())
}

/// The files named by `--data` ([`expand`]), and the record entries (`*.csv`, `*.mat`) of its folders
/// that are not regular files, which were skipped without being opened.
pub struct Expanded {
    /// The files to read: files as given, folders expanded to their `*.csv` and `*.mat` files sorted
    /// by name.
    pub files: Vec<PathBuf>,
    /// The `*.csv` and `*.mat` entries of the folders that are not regular files (a FIFO, a device, a folder, a
    /// link to nothing), with what each is, sorted by name.
    pub skipped: Vec<(PathBuf, &'static str)>,
}

impl Expanded {
    /// The note naming the skipped entries and why (at most [`SKIPPED_SHOWN`] by name), if any.
    pub fn skipped_note(&self) -> Option<String> {
        if self.skipped.is_empty() {
            return None;
        }
        let n = self.skipped.len();
        let mut names: Vec<String> = self
            .skipped
            .iter()
            .take(SKIPPED_SHOWN)
            .map(|(p, what)| format!("{} ({what})", visible(&p.display().to_string())))
            .collect();
        if n > SKIPPED_SHOWN {
            names.push(format!("... ({n} in all)"));
        }
        Some(format!(
            "skipped {n} entr{} of --data named *.csv or *.mat that {} not a regular file and {} not opened: {}",
            if n == 1 { "y" } else { "ies" },
            if n == 1 { "is" } else { "are" },
            if n == 1 { "was" } else { "were" },
            names.join(", ")
        ))
    }
}

/// The most skipped entries [`Expanded::skipped_note`] names.
pub const SKIPPED_SHOWN: usize = 10;

/// What the folder entry `path` is when it is not a regular file (following links; nothing is opened,
/// so a FIFO or a device cannot block the run), `None` for a regular file (audit s22 L-B12: a FIFO, a
/// link to /dev/zero and a link loop named *.csv were skipped without a word).
fn not_regular(path: &Path) -> Option<&'static str> {
    use std::os::unix::fs::FileTypeExt;
    let kind = match std::fs::metadata(path) {
        Ok(m) => m.file_type(),
        Err(_) => {
            return Some(match std::fs::symlink_metadata(path) {
                Ok(l) if l.file_type().is_symlink() => "a link to nothing: broken, or a loop",
                _ => "unreadable",
            })
        }
    };
    if kind.is_file() {
        None
    } else if kind.is_dir() {
        Some("a folder")
    } else if kind.is_fifo() {
        Some("a FIFO")
    } else if kind.is_char_device() || kind.is_block_device() {
        Some("a device")
    } else if kind.is_socket() {
        Some("a socket")
    } else {
        Some("not a regular file")
    }
}

/// The files named by `--data`: files as given, folders expanded to their records — the `*.csv` and
/// `*.mat` files, sorted by name, each read by the one reader of `--data FILE` ([`sysid::data::read_csv`]:
/// CSV text or a MATLAB Level 5 file; audit s23 L-B6: the folder rule alone skipped `.mat` without a
/// word) — and the record entries skipped because they are not regular files.
pub fn expand(paths: &[PathBuf]) -> anyhow::Result<Expanded> {
    let mut files = Vec::new();
    let mut skipped = Vec::new();
    for p in paths {
        if p.is_dir() {
            let mut found = Vec::new();
            let mut other = Vec::new();
            let csv_entries = std::fs::read_dir(p)
                .with_context(|| format!("--data {}: cannot list the folder", p.display()))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|f| is_record_name(f));
            for f in csv_entries {
                match not_regular(&f) {
                    None => found.push(f),
                    Some(what) => other.push((f, what)),
                }
            }
            other.sort();
            if found.is_empty() {
                anyhow::bail!(SysidError::setting(
                    sysid::Setting::Other("--data"),
                    p.display(),
                    &format!(
                        "a folder with at least one record (a *.csv or *.mat file){}",
                        Expanded {
                            files: Vec::new(),
                            skipped: other.clone()
                        }
                        .skipped_note()
                        .map_or(String::new(), |n| format!(" ({n})"))
                    )
                ));
            }
            found.sort();
            files.extend(found);
            skipped.extend(other);
        } else {
            files.push(p.clone());
        }
    }
    Ok(Expanded { files, skipped })
}

/// Whether a folder entry is named as a record: `*.csv` or `*.mat` (any case).
fn is_record_name(path: &Path) -> bool {
    path.extension()
        .is_some_and(|x| x.eq_ignore_ascii_case("csv") || x.eq_ignore_ascii_case("mat"))
}

/// One output line of a successful file.
#[derive(Serialize)]
struct Line<'a> {
    file: String,
    #[serde(flatten)]
    report: &'a IdentifyReport,
}

/// One output line of a failed file.
#[derive(Serialize)]
struct Failure {
    file: String,
    error: String,
}

/// One output line of a record entry of a `--data` folder that is not a regular file (not opened).
#[derive(Serialize)]
struct Skipped {
    file: String,
    skipped: String,
}

/// Runs `identify` in batch mode with the (checked) `settings`; with `--strict`, exits 1 when any
/// file's report carries warnings, without writing the `--json` file (standard output is written).
pub fn run(args: Args, settings: &Identification) -> anyhow::Result<()> {
    if args.save_model.is_some() {
        anyhow::bail!(SysidError::setting(
            sysid::Setting::Other("--save-model"),
            args.save_model
                .as_deref()
                .map(Path::display)
                .map(|d| d.to_string())
                .unwrap_or_default(),
            "a single --data file (in batch mode each line of --json holds its file's model)"
        ));
    }
    if args.val.split.is_some() || (args.val.val_rows.is_some() && args.val.validation.is_none()) {
        anyhow::bail!(
            "--split and --val-rows without --validation split one file; in batch mode (several --data \
             files) pass --rows for the estimation rows of every file and --validation FILE (with \
             --val-rows) for the validation record, or --merge for one model from all files"
        );
    }
    if args.detrend != sysid::detrend::Detrend::None {
        anyhow::bail!(
            "--detrend is not available in batch mode yet; identify the files one by one"
        );
    }
    let expanded = expand(&args.data)?;
    if let Some(note) = expanded.skipped_note() {
        eprintln!("note: {note}");
    }
    let (files, skipped) = (expanded.files, expanded.skipped);
    let mut inputs: Vec<&Path> = files.iter().map(PathBuf::as_path).collect();
    inputs.extend(args.val.validation.as_deref());
    check_outputs(&[(&args.json, "--json")], &inputs)?;
    let opts = args.columns.csv_options(&args.memory);
    let val = args.val.read(&opts, None)?;
    let bar = progress_bar(
        files.len() as u64,
        "{bar:40} {pos}/{len} files  {per_sec}  eta {eta}",
    );
    let start = Instant::now();
    // Each file's report and its record's Ts, or its error.
    let results: Vec<anyhow::Result<(IdentifyReport, f64)>> = files
        .par_iter()
        .map(|path| {
            // The reader's notes (a --ts that contradicts the time column, a resampled gap) join the
            // file's warnings, as `--data FILE` alone says them ("data: …"; audit s24 M-3: the folder
            // run dropped them, so a Ts 100 times wrong went without a word).
            let result = sysid::data::read_record(path, &opts)
                .map_err(anyhow::Error::from)
                .and_then(|record| {
                    let mut report =
                        fit_report(&record.data, settings, val.as_ref(), args.resid_lags)?;
                    report
                        .warnings
                        .extend(super::common::data_notes(&record.notes));
                    Ok((report, record.data.ts()))
                });
            bar.inc(1);
            result
        })
        .collect();
    // Records sampled at different Ts give coefficients per different samples (audit s26 L-5: a
    // folder at 0.01, 0.02 and 10 s went without a word): each odd file's line says so, and the
    // summary below.
    let sampling = Sampling::of(
        results
            .iter()
            .filter_map(|r| r.as_ref().ok().map(|(_, ts)| *ts)),
    );
    // Each line with the exit code its failure would have alone (0 for success) and its warnings.
    let lines: Vec<(String, u8, usize)> = files
        .iter()
        .zip(results)
        .map(|(path, result)| {
            let file = path.display().to_string();
            let line = match result {
                Ok((mut report, ts)) => {
                    report.warnings.extend(sampling.warning_for(ts));
                    (
                        super::common::report_json(
                            &Line {
                                file,
                                report: &report,
                            },
                            false,
                        ),
                        0,
                        report.warnings.len(),
                    )
                }
                Err(e) => (
                    super::common::report_json(
                        &Failure {
                            file,
                            error: crate::exit::render_chain(&e),
                        },
                        false,
                    ),
                    crate::exit::code(&e),
                    0,
                ),
            };
            match line {
                (Ok(text), code, warnings) => (text, code, warnings),
                (Err(e), _, _) => {
                    let f = Failure {
                        file: path.display().to_string(),
                        error: format!("cannot serialise the report: {e}"),
                    };
                    (
                        super::common::report_json(&f, false).unwrap_or_default(),
                        crate::exit::USAGE,
                        0,
                    )
                }
            }
        })
        .collect();
    let elapsed = start.elapsed().as_secs_f64();
    bar.finish_and_clear();
    let failed = lines.iter().filter(|(_, code, _)| *code != 0).count();
    let warned = lines.iter().filter(|(_, _, w)| *w > 0).count();
    let mut body = String::with_capacity(lines.iter().map(|(l, _, _)| l.len() + 1).sum());
    for (l, _, _) in &lines {
        body.push_str(l);
        body.push('\n');
    }
    for (path, what) in &skipped {
        let line = Skipped {
            file: path.display().to_string(),
            skipped: format!("{what}: not a regular file, not opened"),
        };
        body.push_str(&super::common::report_json(&line, false)?);
        body.push('\n');
    }
    // With --strict and any warning, the file is not written, so an earlier one stays (as for one
    // file; audit s16 M10); standard output is always written.
    let total_warnings: usize = lines.iter().map(|(_, _, w)| w).sum();
    let held = match &args.json {
        Some(path) if path.as_os_str() != "-" && args.strict && total_warnings > 0 => Some(path),
        Some(path) => {
            write_output(path, body.as_bytes(), &inputs, "--json")?;
            None
        }
        None => {
            write_output(Path::new("-"), body.as_bytes(), &inputs, "--json")?;
            None
        }
    };
    eprintln!(
        "identified {} of {} files in {:.3} s ({:.1} files/s on {} threads){}",
        files.len() - failed,
        files.len(),
        elapsed,
        files.len() as f64 / elapsed.max(1e-9),
        rayon::current_num_threads(),
        if failed > 0 {
            format!("; {failed} failed (see their \"error\" lines)")
        } else {
            String::new()
        }
    );
    if let Some(summary) = sampling.summary() {
        eprintln!("warning: {summary}");
    }
    // The reasons not to trust a result travel in each line's "warnings"; say that there are some
    // (audit s13 L12: a batch of unstable models printed no warning at all).
    if warned > 0 {
        eprintln!(
            "warning: {warned} of {} identified files have warnings (an unstable model, a poor fit, ...): \
             read each line's \"warnings\" before using its model",
            files.len() - failed
        );
    }
    if failed > 0 {
        // Exit 1 when every failure was numerical, 2 when any file was bad input.
        let msg = format!("{failed} of {} files could not be identified", files.len());
        if lines
            .iter()
            .all(|(_, code, _)| *code == 0 || *code == crate::exit::NUMERICAL)
        {
            anyhow::bail!(SysidError::Numerical(msg));
        }
        anyhow::bail!(SysidError::Data(msg));
    }
    if let Some(path) = held {
        return Err(crate::exit::StrictWarnings {
            warnings: total_warnings,
            not_written: vec![format!("--json {}", path.display())],
        }
        .into());
    }
    crate::exit::strict(args.strict, total_warnings)
}

/// The sampling periods Ts (s) of a run's identified records, grouped (equal to 1e-9 relative), the
/// most common first (the smaller Ts on a tie).
struct Sampling {
    groups: Vec<(f64, usize)>,
}

impl Sampling {
    fn of(ts: impl Iterator<Item = f64>) -> Self {
        let mut groups: Vec<(f64, usize)> = Vec::new();
        for t in ts {
            match groups
                .iter_mut()
                .find(|(g, _)| (t - *g).abs() <= 1e-9 * g.abs().max(t.abs()))
            {
                Some((_, n)) => *n += 1,
                None => groups.push((t, 1)),
            }
        }
        groups.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.total_cmp(&b.0)));
        Sampling { groups }
    }

    /// The Ts most records of the run share, when they do not all share one.
    fn common(&self) -> Option<(f64, usize)> {
        (self.groups.len() > 1).then(|| self.groups[0])
    }

    /// The warning of a record sampled every `ts` s when the run's common Ts differs from it.
    fn warning_for(&self, ts: f64) -> Option<String> {
        let (common, n) = self.common()?;
        let total: usize = self.groups.iter().map(|(_, n)| n).sum();
        ((ts - common).abs() > 1e-9 * common.abs().max(ts.abs())).then(|| {
            format!(
                "batch: this record is sampled every {ts} s, {n} of the run's {total} identified \
                 records every {common} s: a model's coefficients are per sample of its own record, \
                 so this one cannot be compared with theirs (a time column in ms or µs needs \
                 --time-unit; --resample SECONDS puts records on one Ts)"
            )
        })
    }

    /// The run's sampling periods in words when they differ.
    fn summary(&self) -> Option<String> {
        self.common()?;
        let parts: Vec<String> = self
            .groups
            .iter()
            .map(|(ts, n)| format!("{ts} s ({n} file{})", if *n == 1 { "" } else { "s" }))
            .collect();
        Some(format!(
            "the records' sampling times differ: Ts = {}; their models' coefficients are per sample \
             of different lengths and cannot be compared (each odd file's line says so)",
            parts.join(", ")
        ))
    }
}

/// The single-file pipeline of `identify` on one record: fit, refuse non-finite estimates, metrics on the
/// record and on the validation record.
fn fit_report(
    data: &Dataset,
    settings: &Identification,
    val: Option<&Dataset>,
    resid_lags: usize,
) -> anyhow::Result<IdentifyReport> {
    let fit = identify(data, settings)?;
    Ok(IdentifyReport::assemble(
        &fit,
        settings,
        std::slice::from_ref(data),
        val,
        resid_lags,
    )?)
}
