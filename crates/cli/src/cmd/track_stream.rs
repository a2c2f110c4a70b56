//! `track`'s stream: CSV lines as they arrive, read by the CSV rules of `identify`
//! ([`sysid::data::lines::CsvLines`]: the same header, delimiter, quoting and number rules), each sample
//! pushed to the [`Tracker`], a [`TrackLine`] written as one JSON line every `every` samples and at every
//! detected change, and the [`TrackSummary`] at the end.
//!
//! A line is read into a buffer of at most [`MAX_LINE_BYTES`] bytes: a stream that stops sending line ends
//! (`/dev/zero`, a wrong baud rate) is an error naming the line, not a buffer that grows until memory runs
//! out.

use std::io::{BufRead, Write};
use sysid_core::format::Shortest;

use serde::Serialize;
use sysid::data::lines::CsvLines;
use sysid::data::CsvOptions;
use sysid::online::Tracker;
use sysid::{Model, Setting, SysidError};
use sysid_summary::{poles, Pole};

/// Upper bound on the length of one line of a tracked stream, bytes: every CSV reader's bound on a line
/// (a line of t,u,y is under 100).
pub use sysid::data::MAX_LINE_BYTES;

/// Where the columns of a streamed CSV are, and how often to report.
#[derive(Debug, Clone)]
pub struct StreamOptions {
    /// The source's name in messages (`<stdin>`, a path).
    pub name: String,
    /// The columns u, y and t, the unit of t (`--time-unit`) and Ts (`--ts`; `None`: the difference of
    /// the first two times; with it the t column is optional, then t = k Ts). The other reader options
    /// do not apply to a stream.
    pub csv: CsvOptions,
    /// Print a line every `every` samples (≥ 1), and at every detected change.
    pub every: usize,
    /// A followed file's restarts (`--follow`: truncated or rewritten, read again from its beginning;
    /// [`sysid_io::Restarts`]): line numbers count in the new content and time starts again there.
    pub restarts: Option<std::sync::Arc<sysid_io::Restarts>>,
    /// A live source (`--follow`, `--serial`, standard input from a pipe): when it ends (idle
    /// time-out, Ctrl-C, hang-up, the logger's end) a last line without its line end was never finished
    /// (a logger stopped, a cable pulled mid-line) and is dropped with a warning, not read as a row
    /// (audit s36 M-3: it ended the run with a parse error, no summary and no `--json`). A file, or
    /// standard input redirected from one, is read to its end with such a line: a finished file may end
    /// without a line end.
    pub live: bool,
}

/// One JSON line of `track`.
#[derive(Debug, Clone, Serialize)]
pub struct TrackLine {
    /// Sample index k (0-based data row).
    pub k: usize,
    /// Time t(k) (s).
    pub t: f64,
    /// The current estimate (the `model` object of `identify --json`).
    pub model: Model,
    /// Its poles.
    pub poles: Vec<Pole>,
    /// The model settles: its stability verdict (`Model::stability`) is `settles`, every pole inside
    /// the unit circle by more than ε = 10⁻⁵ (as `identify`'s `stable`).
    pub stable: bool,
    /// The stability verdict's name (`sysid_core::Stability::name`): `settles`, `integrator`,
    /// `on_circle` or `unstable`, as `identify`'s `stability`.
    pub stability: &'static str,
    /// A change was detected at this sample or since the previous line.
    pub change: bool,
    /// RMS of the last `pe_window` a-priori prediction errors (mm).
    pub pe_rms: Option<f64>,
    /// Number of errors in `pe_rms`.
    pub pe_window: usize,
    /// The CUSUM statistic g(k) (`null` while the detector warms up or calibrates).
    pub cusum: Option<f64>,
    /// Reasons not to trust this line, in words.
    pub warnings: Vec<String>,
}

/// A detected change.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ChangePoint {
    /// Sample index.
    pub k: usize,
    /// Time (s).
    pub t: f64,
    /// The CUSUM threshold h the change was judged against (the one in force before this sample:
    /// after an alarm the detector re-arms and calibrates again, so the summary's `detector_threshold`
    /// is a later one; audit s35b L-5).
    pub threshold: Option<f64>,
}

/// The end of a `track` run (`--json`).
#[derive(Debug, Clone, Serialize)]
pub struct TrackSummary {
    /// Samples read.
    pub samples: usize,
    /// Time of the last sample (s).
    pub t_end: Option<f64>,
    /// The final estimate (`None` when fewer than k0 + 1 samples came).
    pub model: Option<Model>,
    /// Its poles.
    pub poles: Vec<Pole>,
    /// The model settles: its stability verdict (`Model::stability`) is `settles`, every pole inside
    /// the unit circle by more than ε = 10⁻⁵ (as `identify`'s `stable`).
    pub stable: Option<bool>,
    /// The stability verdict's name (`settles`, `integrator`, `on_circle`, `unstable`; `None` without
    /// a model), as `identify`'s `stability`.
    pub stability: Option<&'static str>,
    /// RMS of the last prediction errors (mm).
    pub pe_rms: Option<f64>,
    /// Detected changes.
    pub change_points: Vec<ChangePoint>,
    /// The CUSUM threshold in force at the end ([`Tracker::detector_threshold`]; `None` without a
    /// detector); each change point carries the one it was judged against.
    pub detector_threshold: Option<f64>,
    /// Samples at which the deadzone guard replaced an implausible branch.
    pub guard_interventions: usize,
    /// Reasons not to trust the final model, in words.
    pub warnings: Vec<String>,
}

/// The most time jumps listed one by one in the warnings (the rest are counted).
const MAX_JUMPS_LISTED: usize = 10;

/// The columns of u, y and (when there is one) t.
type Columns = (usize, usize, Option<usize>);

/// What [`read_line_bounded`] carries from one line to the next.
#[derive(Debug, Default)]
struct LineState {
    /// A CR ended the bytes read so far: the LF of a CRLF cut between two reads is skipped next.
    after_cr: bool,
    /// A followed file was read again from its beginning and nothing of the new content has been
    /// read yet: NUL bytes at its start are skipped (and counted in `nuls`).
    skip_nuls: bool,
    /// NUL bytes skipped at the start of a followed file's new content (audit s36 L-5: a logger that
    /// does not append writes on at its old offset after a copy-and-truncate rotation, and the file
    /// starts with a hole of that many NULs); the caller takes and reports them.
    nuls: u64,
}

/// Reads one line of `input` into `buf` (cleared first; the line end stays), at most `max` bytes;
/// `Ok(None)` at the end of the input, else `Ok(Some(dropped))`. A longer line is an error of kind
/// `InvalidData`, raised once `max` bytes have come without a line end (nothing more is buffered).
/// `restarts`: those of a followed file ([`sysid_io::Restarts`]); when the file is read again from its
/// beginning while a line is unfinished (its last line was cut by a copy-truncate rotation), the
/// unfinished bytes are dropped rather than joined to the new content's first line, and `dropped` is
/// their number (0 when nothing was dropped).
///
/// After a restart the NUL bytes that start the new content are skipped, counted in `state.nuls`
/// (a hole left by a logger that writes at its old offset: [`LineState::nuls`]).
///
/// A line ends at LF, CRLF or a lone CR, as in every other reader (audit s30 M-3: a file with CR line
/// ends was one line to `track`): a CR that ends what has come so far sets `state.after_cr`, and the LF
/// of a CRLF cut between two reads is then skipped at the next call, not read as a blank line.
fn read_line_bounded<R: BufRead>(
    input: &mut R,
    buf: &mut Vec<u8>,
    max: usize,
    restarts: Option<&sysid_io::Restarts>,
    state: &mut LineState,
) -> std::io::Result<Option<usize>> {
    buf.clear();
    let mut dropped = 0;
    let mut seen = restarts.map(sysid_io::Restarts::count);
    loop {
        let available = match input.fill_buf() {
            Ok(a) => a,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e),
        };
        // A restart happens inside `fill_buf` (the followed file's reader), whose bytes are then the new
        // content's: what `buf` holds is the old content's unfinished last line.
        let now = restarts.map(sysid_io::Restarts::count);
        if now != seen {
            seen = now;
            dropped += buf.len();
            buf.clear();
            state.after_cr = false;
            state.skip_nuls = true;
        }
        if available.is_empty() {
            return Ok((!buf.is_empty() || dropped > 0).then_some(dropped));
        }
        if state.skip_nuls {
            let nuls = available.iter().take_while(|&&b| b == 0).count();
            if nuls > 0 {
                state.nuls += nuls as u64;
                input.consume(nuls);
                continue;
            }
            state.skip_nuls = false;
        }
        if std::mem::take(&mut state.after_cr) && available.first() == Some(&b'\n') {
            input.consume(1); // the LF of a CRLF whose CR ended the line before
            continue;
        }
        let (take, done) = match available.iter().position(|&b| b == b'\n' || b == b'\r') {
            Some(i) if available[i] == b'\r' => match available.get(i + 1) {
                Some(b'\n') => (i + 2, true),
                Some(_) => (i + 1, true),
                None => {
                    state.after_cr = true;
                    (i + 1, true)
                }
            },
            Some(i) => (i + 1, true),
            None => (available.len(), false),
        };
        if buf.len() + take > max + 1 {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                "line too long",
            ));
        }
        buf.extend_from_slice(&available[..take]);
        input.consume(take);
        if done {
            return Ok(Some(dropped));
        }
    }
}

/// A line read by [`read_line_bounded`] without its line end (LF, CRLF or CR).
fn line_body(mut line: &[u8]) -> &[u8] {
    while let [rest @ .., b'\n' | b'\r'] = line {
        line = rest;
    }
    line
}

/// Runs `tracker` over CSV lines from `input` (a header row, then data rows; blank lines skipped),
/// writing a [`TrackLine`] as one JSON line to `out` every `options.every` samples and at every detected
/// change, each flushed at once. Returns the summary at the end of the input. A malformed line stops the
/// run with an error naming its line and column.
pub fn track_stream<R: BufRead, W: Write>(
    mut input: R,
    out: &mut W,
    tracker: &mut Tracker,
    options: &StreamOptions,
) -> Result<TrackSummary, SysidError> {
    if options.every == 0 {
        return Err(SysidError::setting(
            Setting::Other("--every"),
            0,
            "at least 1 sample",
        ));
    }
    if let Some(ts) = options.csv.ts {
        // The one rule of every Ts (`identify --ts`, a model file's, the controller's): audit s32 L-11.
        sysid::data::check_ts(ts)?;
    }
    let write_err = |e: std::io::Error| SysidError::Io {
        path: "<output>".into(),
        source: e,
    };
    let mut buf = Vec::with_capacity(256);
    let mut line_no = 0;
    // The reader, once the header has come, and the columns of u, y and t.
    let mut reader: Option<(CsvLines, Columns)> = None;
    // The header line read first: said when a rotated file's new content starts with another one.
    let mut first_header: Vec<u8> = Vec::new();
    let mut ts = options.csv.ts;
    // The step later time steps are checked against: Ts, or the column's own first step when --ts
    // contradicts it (said once, as identify says it, not as a "time jump" at every sample).
    let mut step_ref: Option<f64> = None;
    let mut t_last: Option<f64> = None;
    let mut pending_change = false;
    let mut change_points = Vec::new();
    // Time that jumps (samples missing, a clock reset forwards): warnings for the next line and the end.
    let (mut time_jumps, mut new_time_warnings, mut time_warnings) =
        (0usize, Vec::new(), Vec::new());
    let mut restarts_seen = 0u64;
    // After a restart: the note on its first sample (line and time of the new content).
    let mut restarted: Option<(u64, bool)> = None;
    let mut line_state = LineState::default();
    // The range of u and y so far: a signal too small for f64's sums of squares is said in the
    // words of `identify`'s refusal (`sysid::estimate::tiny_signal`).
    let mut range = sysid::DataRange {
        u: vec![[f64::INFINITY, f64::NEG_INFINITY]],
        y: [f64::INFINITY, f64::NEG_INFINITY],
    };
    let u_name = [options.csv.u_col.as_str()];
    let tiny = |range: &sysid::DataRange| {
        sysid::estimate::tiny_signal(range, &u_name, &options.name).map(|e| match e {
            SysidError::Numerical(m) => m,
            e => e.to_string(),
        })
    };
    loop {
        // A stop asked by the first Ctrl-C of a followed source (`sysid_io::accept_stop`): the run ends
        // here, between two lines, even when the data never pause (a port streaming without a gap).
        if sysid_io::stop_asked() {
            break;
        }
        match read_line_bounded(
            &mut input,
            &mut buf,
            MAX_LINE_BYTES,
            options.restarts.as_deref(),
            &mut line_state,
        ) {
            Ok(Some(0)) => {}
            Ok(Some(dropped)) => {
                // The followed file's last line was unfinished when it was truncated (audit s23 L-B5).
                let w = format!(
                    "{}: the followed file's last line was unfinished ({dropped} bytes without a line end) \
                     when it was read again from its beginning; that partial line was dropped, not joined \
                     to the new content's first line",
                    options.name
                );
                new_time_warnings.push(w);
            }
            Ok(None) => break,
            Err(e) if e.kind() == std::io::ErrorKind::InvalidData => {
                return Err(SysidError::Parse {
                    file: options.name.clone(),
                    line: line_no + 1,
                    column: 1,
                    message: format!(
                        "the line is longer than {MAX_LINE_BYTES} bytes (no line end: binary data, or a \
                         wrong baud rate?); expected CSV lines such as 0.01,12,3.5"
                    ),
                })
            }
            Err(source) => {
                return Err(SysidError::Io {
                    path: options.name.clone().into(),
                    source,
                })
            }
        }
        // A followed file read again from its beginning (log rotation by copy and truncate; audit s23
        // L-B5): this line is the first of the new content. Its lines are counted from its start (line
        // 2 when the header line was skipped) and its clock may start again: the time check starts
        // again at its first sample (a new time origin, said in a warning), the model is kept.
        if let Some(r) = &options.restarts {
            let count = r.count();
            if count != restarts_seen {
                restarts_seen = count;
                line_no = usize::from(r.header_skipped());
                t_last = None;
                restarted = Some((count, r.header_skipped()));
            }
        }
        // A followed file whose new content starts with a hole of NULs (audit s36 L-5: it ended the run
        // with "the header changed (columns moved?)", no summary and no --json): said, and the rows
        // after the hole are read. A header line after the hole, the one read first, is skipped.
        let nuls = std::mem::take(&mut line_state.nuls);
        if nuls > 0 {
            new_time_warnings.push(format!(
                "{}: the followed file starts with {nuls} NUL bytes after it was read again from its \
                 beginning: the logger writes at its old offset (it does not append), so the copy and \
                 truncate rotation left a hole of zeros up to it; the NUL bytes were skipped and the \
                 rows after them read (open the log in append mode, O_APPEND / open(..., \"a\"), so \
                 that a rotation leaves no hole)",
                options.name
            ));
            if !first_header.is_empty() && line_body(&buf) == first_header.as_slice() {
                continue;
            }
        }
        // A live source's end inside a line: the line was never finished.
        let unended = !buf.is_empty() && !buf.ends_with(b"\n") && !buf.ends_with(b"\r");
        if options.live && unended {
            time_warnings.push(format!(
                "{}: the source ended inside its last line ({} bytes without a line end: the logger \
                 stopped or the connection broke mid-line); that unfinished line was dropped, not read \
                 (data that end without a final line end: add one, or pass the file with --data FILE)",
                options.name,
                buf.len()
            ));
            break;
        }
        line_no += 1;
        let line = line_body(&buf);
        if line.iter().all(u8::is_ascii_whitespace) {
            continue;
        }
        let Some((csv, (ucol, ycol, tcol))) = &mut reader else {
            let csv = CsvLines::from_header(line, &options.name)?;
            first_header = line.to_vec();
            // track has no --no-header: a header-less file's hint names what it needs instead.
            let cols = csv.columns(&options.csv).map_err(|mut e| {
                if let SysidError::MissingColumn { hint: Some(h), .. } = &mut e {
                    if **h == sysid::error::ColumnHint::NoHeader {
                        **h = sysid::error::ColumnHint::HeaderNeeded;
                    }
                }
                e
            })?;
            reader = Some((csv, cols));
            continue;
        };
        // The first line of a followed file's new content (after a restart) that does not read as
        // data, not skipped as the header read first: the new content starts with another header
        // (columns moved), said so (audit s27 L-3).
        let header_changed = |e: SysidError| {
            match e {
            SysidError::Parse {
                file,
                line,
                column,
                message,
            } if matches!(restarted, Some((_, false))) => SysidError::Parse {
                file,
                line,
                column,
                message: format!(
                    "{message}: the followed file was read again from its beginning (log rotation?) and \
                     its new content does not start with the header line read first ({:?}): the header \
                     changed (columns moved?), so track stops: start it again on the new file",
                    String::from_utf8_lossy(&first_header)
                ),
            },
            e => e,
        }
        };
        if !csv.read_line(line, line_no).map_err(header_changed)? {
            continue;
        }
        let (u, y) = (
            csv.value(*ucol, line_no).map_err(header_changed)?,
            csv.value(*ycol, line_no).map_err(header_changed)?,
        );
        let k = tracker.samples();
        // t in s: the column scaled by --time-unit, else k Ts.
        let t = match (*tcol, ts) {
            (Some(c), _) => {
                csv.value(c, line_no).map_err(header_changed)? * options.csv.time_unit.seconds()
            }
            (None, Some(ts)) => k as f64 * ts,
            (None, None) => f64::NAN, // not reached: a missing t column needs `ts`
        };
        if let (Some(tc), Some(prev)) = (*tcol, t_last) {
            match step_ref {
                // The second sample: the column's first step gives Ts (without --ts), or is set
                // against --ts, with the reader's words (`sysid::data`: the ms hint, the contradiction).
                None => {
                    let d = t - prev;
                    match ts {
                        None => {
                            increasing(prev, t, line_no, tc, &options.name)?;
                            ts = Some(d);
                            new_time_warnings.extend(sysid::data::milliseconds_hint(
                                &[prev, t],
                                d,
                                options.csv.time_unit,
                                &options.csv.t_col,
                            ));
                        }
                        Some(given) => {
                            check_time_step(prev, t, given, line_no, tc, &options.name)?;
                            let note =
                                sysid::data::ts_contradiction_note(given, &options.csv.t_col, d);
                            if note.is_none() {
                                step_ref = Some(given);
                            }
                            new_time_warnings.extend(note);
                        }
                    }
                    step_ref.get_or_insert(d);
                }
                Some(step) => {
                    if let Some(w) = check_time_step(prev, t, step, line_no, tc, &options.name)? {
                        time_jumps += 1;
                        if time_jumps <= MAX_JUMPS_LISTED {
                            new_time_warnings.push(w);
                        }
                    }
                }
            }
        }
        if let Some((count, header)) = restarted.take() {
            let w = format!(
                "{}: the followed file was read again from its beginning (restart {count}: truncated, \
                 rewritten or replaced; log rotation?); from line {line_no} of the new content{} on, time starts \
                 again at t = {} s (a new time origin: times are not compared across the restart) and \
                 the model estimated so far is kept",
                options.name,
                if header { " (after its header line)" } else { "" },
                Shortest(t)
            );
            // Said once: in the next JSON line and in the summary (it was put in both lists, so the
            // summary said it twice).
            new_time_warnings.push(w);
        }
        t_last = Some(t);
        let threshold = tracker.detector_threshold();
        let step = tracker.push(u, y).map_err(|e| match e {
            SysidError::Numerical(m) => {
                SysidError::Numerical(format!("{}:{line_no}: {m}", options.name))
            }
            e => e,
        })?;
        if step.change {
            change_points.push(ChangePoint { k, t, threshold });
            pending_change = true;
        }
        for (r, v) in range.u.iter_mut().chain([&mut range.y]).zip([u, y]) {
            r[0] = r[0].min(v);
            r[1] = r[1].max(v);
        }
        // A finished file that ends inside its last row: the in-memory reader's note of a file cut
        // inside its last number (audit s35 M-2), by its rule and in its words.
        if unended {
            time_warnings.extend(csv.cut_note(line_no));
        }
        if step.error.is_some() && (step.change || (k + 1) % options.every == 0) {
            if let Some(ts) = ts {
                let mut line = track_line(tracker, k, t, ts, pending_change)?;
                line.warnings.extend(tiny(&range));
                line.warnings.extend(new_time_warnings.iter().cloned());
                time_warnings.append(&mut new_time_warnings);
                serde_json::to_writer(&mut *out, &line).map_err(|e| {
                    SysidError::Numerical(format!("a track line could not be written: {e}"))
                })?;
                out.write_all(b"\n").map_err(write_err)?;
                out.flush().map_err(write_err)?;
                pending_change = false;
            }
        }
    }
    if reader.is_none() {
        return Err(SysidError::File {
            file: options.name.clone(),
            message: "no header row arrived; expected a header such as t,u,y and data rows".into(),
        });
    }
    // A source that ended after its header tracked nothing: an error, as the other commands' reader
    // says of the same file (audit s19 L-8: exit 0 and a warning), whether it ended by itself, at the
    // idle time-out or by Ctrl-C (audit s36 L-10: the stop wrote a summary with `"model": null`,
    // exit 0, where the idle time-out refused the same run).
    if tracker.samples() == 0 {
        return Err(SysidError::File {
            file: options.name.clone(),
            message: if sysid_io::stop_asked() {
                "stopped by a signal after the header and before any data row: nothing was tracked"
                    .into()
            } else {
                "the file has a header but no data rows".into()
            },
        });
    }
    let mut summary = summary(tracker, ts, t_last, change_points)?;
    summary.warnings.extend(tiny(&range));
    time_warnings.append(&mut new_time_warnings);
    // The jumps listed are the first MAX_JUMPS_LISTED (the other time warnings — a restart, a partial
    // line, the milliseconds hint — are not jumps).
    if time_jumps > MAX_JUMPS_LISTED {
        time_warnings.push(format!(
            "{time_jumps} time jumps in all (the first {MAX_JUMPS_LISTED} are listed)"
        ));
    }
    summary.warnings.extend(time_warnings);
    Ok(summary)
}

/// Checks the time t of a sample after `prev` (line `line_no`, 0-based column `col` of `name`) against
/// the expected step `ts` (Ts, or the column's own step when `--ts` contradicts it, which is said
/// once): time that does not increase is an error (a logger restarted, a file rotated); a step more than
/// 50 % away from Ts is returned as a warning (samples missing, or the clock jumped), because the
/// estimator treats the samples as Ts apart.
fn check_time_step(
    prev: f64,
    t: f64,
    ts: f64,
    line_no: usize,
    col: usize,
    name: &str,
) -> Result<Option<String>, SysidError> {
    increasing(prev, t, line_no, col, name)?;
    let d = t - prev;
    Ok(((d - ts).abs() > 0.5 * ts).then(|| {
        format!(
            "{name}:{line_no}: time jumps from {} to {} s (a step of {} s where Ts = {} s): samples \
             missing or the clock jumped; the estimate treats the samples as Ts apart",
            Shortest(prev),
            Shortest(t),
            Shortest(d),
            Shortest(ts)
        )
    }))
}

/// Checks that time t (s, line `line_no`, 0-based column `col` of `name`) increases after `prev` by
/// the readers' rule and words ([`sysid::data::increasing_time`]), with `track`'s advice.
fn increasing(prev: f64, t: f64, line_no: usize, col: usize, name: &str) -> Result<(), SysidError> {
    sysid::data::increasing_time(&[prev, t]).map_err(|fault| SysidError::Parse {
        file: name.to_string(),
        line: line_no,
        column: col + 1,
        message: format!(
            "{fault} (a restarted logger or a rotated file: start track again on the new record)"
        ),
    })
}

fn track_line(
    tracker: &Tracker,
    k: usize,
    t: f64,
    ts: f64,
    change: bool,
) -> Result<TrackLine, SysidError> {
    let model = tracker.model(ts)?;
    Ok(TrackLine {
        k,
        t,
        poles: poles(&model),
        stable: model.stability().settles(),
        stability: model.stability().name(),
        change,
        pe_rms: tracker.pe_rms(),
        pe_window: tracker.pe_count(),
        cusum: tracker.detector_state().map(|(g, _)| g),
        warnings: tracker.warnings(&model),
        model,
    })
}

fn summary(
    tracker: &Tracker,
    ts: Option<f64>,
    t_end: Option<f64>,
    change_points: Vec<ChangePoint>,
) -> Result<TrackSummary, SysidError> {
    let model = match ts {
        Some(ts) if tracker.samples() > tracker.k0() => Some(tracker.model(ts)?),
        _ => None,
    };
    let mut warnings = match &model {
        Some(m) => tracker.warnings(m),
        None => vec![format!(
            "{} sample(s): no regression update was made (k0 = {}), so there is no model",
            tracker.samples(),
            tracker.k0()
        )],
    };
    warnings.retain(|w| !w.starts_with("the change detector"));
    warnings.extend(tracker.detector_unarmed_warning());
    warnings.extend(tracker.blended_model_warning());
    warnings.extend(tracker.input_warnings(model.as_ref()));
    Ok(TrackSummary {
        samples: tracker.samples(),
        t_end,
        poles: model.as_ref().map(poles).unwrap_or_default(),
        stable: model.as_ref().map(|m| m.stability().settles()),
        stability: model.as_ref().map(|m| m.stability().name()),
        model,
        pe_rms: tracker.pe_rms(),
        change_points,
        detector_threshold: tracker.detector_threshold(),
        guard_interventions: tracker.guard_interventions(),
        warnings,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    // A line of `max` bytes plus its line end is read whole; one byte more without a line end is refused
    // after max + 1 bytes, whatever follows.
    #[test]
    fn a_line_is_read_up_to_its_bound() {
        let mut buf = Vec::new();
        let mut ok: &[u8] = b"abcd\nrest";
        assert_eq!(
            read_line_bounded(&mut ok, &mut buf, 4, None, &mut LineState::default()).unwrap(),
            Some(0)
        );
        assert_eq!(buf, b"abcd\n");
        assert_eq!(
            read_line_bounded(&mut ok, &mut buf, 4, None, &mut LineState::default()).unwrap(),
            Some(0)
        );
        assert_eq!(buf, b"rest");
        assert_eq!(
            read_line_bounded(&mut ok, &mut buf, 4, None, &mut LineState::default()).unwrap(),
            None
        );
        let mut long = std::io::BufReader::with_capacity(2, std::io::repeat(b'x'));
        let e =
            read_line_bounded(&mut long, &mut buf, 4, None, &mut LineState::default()).unwrap_err();
        assert_eq!(e.kind(), std::io::ErrorKind::InvalidData);
        assert!(buf.len() <= 5, "{}", buf.len());
    }

    // Audit s30 M-3: LF, CRLF and lone CR all end a line, and a CRLF cut between two reads (a reader
    // that hands out 3 bytes at a time) is one line end, not a line and a blank one.
    #[test]
    fn every_line_end_ends_a_line() {
        for text in [
            &b"a,b\r1,2\r3,4\r"[..],
            b"a,b\r\n1,2\r\n3,4\r\n",
            b"a,b\n1,2\r3,4",
        ] {
            for cap in [1, 2, 3, 64] {
                let mut r = std::io::BufReader::with_capacity(cap, text);
                let (mut buf, mut state, mut lines) =
                    (Vec::new(), LineState::default(), Vec::new());
                while read_line_bounded(&mut r, &mut buf, 16, None, &mut state)
                    .unwrap()
                    .is_some()
                {
                    let l: Vec<u8> = buf
                        .iter()
                        .copied()
                        .filter(|b| *b != b'\r' && *b != b'\n')
                        .collect();
                    lines.push(String::from_utf8(l).unwrap());
                }
                assert_eq!(lines, ["a,b", "1,2", "3,4"], "{text:?} cap {cap}");
            }
        }
    }

    /// A reader that runs `hook` with its call number before each read of `inner`.
    struct Hooked<R, F> {
        inner: R,
        calls: usize,
        hook: F,
    }

    impl<R: std::io::Read, F: FnMut(usize)> std::io::Read for Hooked<R, F> {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            self.calls += 1;
            (self.hook)(self.calls);
            self.inner.read(buf)
        }
    }

    // Audit s23 L-B5, deterministically (no thread, no sleep deciding the outcome): a followed file whose
    // last line is unfinished ("0.5,0.") is truncated and written again (a copy-truncate rotation, the
    // new content shorter than what was read, so the reader finds the end of the file first and then the
    // truncation) between two reads of the same thread. The partial line is dropped, not joined to the
    // new content's first line (which would read 0.5,0.0,1,2 — a ragged row — or, header skipped, a
    // wrong sample); it is said once, and the restart's warning is said once in the summary (it was put
    // there twice). Every sample of both contents is tracked: 50 + 20.
    #[test]
    fn a_partial_line_cut_by_a_rotation_is_dropped_and_said_once() {
        let rows = |n: usize, t0: usize| -> String {
            (0..n)
                .map(|k| {
                    format!(
                        "{},{},{}\n",
                        (t0 + k) as f64 * 0.01,
                        (k % 3) as f64 - 1.0,
                        k % 5
                    )
                })
                .collect()
        };
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("live.csv");
        let first = format!("t,u,y\n{}0.5,0.", rows(50, 0));
        let second = format!("t,u,y\n{}", rows(20, 0));
        assert!(second.len() < first.len());
        std::fs::write(&path, &first).unwrap();
        let follow = sysid_io::Follow::file(
            &path,
            Some(std::time::Duration::from_secs(2)),
            std::time::Duration::from_millis(5),
        )
        .unwrap();
        let restarts = follow.restarts();
        let p = path.clone();
        let rotate = move |call: usize| {
            if call == 2 {
                let f = std::fs::OpenOptions::new().write(true).open(&p).unwrap();
                f.set_len(0).unwrap();
                drop(f);
                std::fs::write(&p, &second).unwrap();
            }
        };
        let input = std::io::BufReader::new(Hooked {
            inner: follow,
            calls: 0,
            hook: rotate,
        });
        let mut tracker = Tracker::new(sysid::online::TrackSettings {
            kind: sysid::ModelKind::Arx,
            ..Default::default()
        })
        .unwrap();
        let options = StreamOptions {
            name: "live.csv".into(),
            csv: CsvOptions::default(),
            every: 10,
            restarts: Some(restarts),
            live: true,
        };
        let mut out = Vec::new();
        let summary = track_stream(input, &mut out, &mut tracker, &options).unwrap();
        assert_eq!(summary.samples, 70, "{:?}", summary.warnings);
        let count = |what: &str| summary.warnings.iter().filter(|w| w.contains(what)).count();
        assert_eq!(
            count("read again from its beginning (restart 1"),
            1,
            "{:?}",
            summary.warnings
        );
        assert_eq!(
            count("last line was unfinished (6 bytes without a line end)"),
            1,
            "{:?}",
            summary.warnings
        );
        assert_eq!(
            count("from line 2 of the new content (after its header line) on"),
            1
        );
    }

    // Audit s36 L-5: copy and truncate under a logger that does not append. The followed file (a
    // header and 50 rows, P bytes) is truncated to 0 between two reads of the reader's thread, and the
    // "logger" then writes 20 more rows at its own offset P, so the file is P NUL bytes and those rows.
    // The run goes on: the 50 + 20 samples are tracked (no "header changed" error), and a warning says
    // the file starts with P NUL bytes (P counted here from the text written) and why.
    #[test]
    fn a_hole_of_nuls_after_a_copy_truncate_is_skipped_and_said() {
        let rows = |n: usize, k0: usize| -> String {
            (k0..k0 + n)
                .map(|k| format!("{},{},{}\n", k as f64 * 0.01, (k % 3) as f64 - 1.0, k % 5))
                .collect()
        };
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("ct.csv");
        let first = format!("t,u,y\n{}", rows(50, 0));
        let later = rows(20, 50);
        let hole = first.len();
        std::fs::write(&path, &first).unwrap();
        let follow = sysid_io::Follow::file(
            &path,
            Some(std::time::Duration::from_millis(1500)),
            std::time::Duration::from_millis(5),
        )
        .unwrap();
        let restarts = follow.restarts();
        let p = path.clone();
        let rotate = move |call: usize| {
            if call == 2 {
                std::fs::OpenOptions::new()
                    .write(true)
                    .open(&p)
                    .unwrap()
                    .set_len(0)
                    .unwrap();
                let (p, later) = (p.clone(), later.clone());
                // The logger writes on at its offset (no O_APPEND) a moment later. Whether the reader
                // sees the file empty first or already rewritten, it reads it again from byte 0.
                std::thread::spawn(move || {
                    use std::io::{Seek, Write};
                    std::thread::sleep(std::time::Duration::from_millis(100));
                    let mut f = std::fs::OpenOptions::new().write(true).open(&p).unwrap();
                    f.seek(std::io::SeekFrom::Start(hole as u64)).unwrap();
                    f.write_all(later.as_bytes()).unwrap();
                });
            }
        };
        let input = std::io::BufReader::new(Hooked {
            inner: follow,
            calls: 0,
            hook: rotate,
        });
        let mut tracker = Tracker::new(sysid::online::TrackSettings {
            kind: sysid::ModelKind::Arx,
            ..Default::default()
        })
        .unwrap();
        let options = StreamOptions {
            name: "ct.csv".into(),
            csv: CsvOptions::default(),
            every: 10,
            restarts: Some(restarts),
            live: true,
        };
        let summary = track_stream(input, &mut Vec::new(), &mut tracker, &options).unwrap();
        assert_eq!(summary.samples, 70, "{:?}", summary.warnings);
        let said: Vec<_> = summary
            .warnings
            .iter()
            .filter(|w| w.contains(&format!("starts with {hole} NUL bytes")))
            .collect();
        assert_eq!(said.len(), 1, "{:?}", summary.warnings);
        assert!(said[0].contains("append mode"), "{}", said[0]);
    }

    // Audit s35 M-2 for `track --data FILE`: a finished file whose last row ends without a line end and
    // whose last cell has fewer digits than the column's cells before it ("10" under values of 6
    // digits) gets the in-memory reader's note, with that row's line and column (line 13: the header
    // and 12 rows; column 3); the same file with its last value whole (6 digits) gets none, and so
    // does the cut file when it ends with a line end (then it is not known to be cut).
    #[test]
    fn a_file_cut_inside_its_last_number_is_noted() {
        let mut text = String::from("t,u,y\n");
        for k in 0..11 {
            text.push_str(&format!(
                "{},{},{}\n",
                k as f64 * 0.01,
                k % 3,
                100.125 + k as f64
            ));
        }
        let options = StreamOptions {
            name: "cut.csv".into(),
            csv: CsvOptions::default(),
            every: 100,
            restarts: None,
            live: false,
        };
        let run = |text: &str| {
            let mut tracker = Tracker::new(sysid::online::TrackSettings {
                kind: sysid::ModelKind::Arx,
                ..Default::default()
            })
            .unwrap();
            track_stream(
                std::io::Cursor::new(text.as_bytes()),
                &mut Vec::new(),
                &mut tracker,
                &options,
            )
            .unwrap()
            .warnings
        };
        let noted = |w: &[String]| {
            w.iter()
                .filter(|w| w.contains("the file ends inside its last row, without a line end"))
                .cloned()
                .collect::<Vec<_>>()
        };
        let cut = format!("{text}0.11,2,10");
        let w = run(&cut);
        let n = noted(&w);
        assert_eq!(n.len(), 1, "{w:?}");
        assert!(n[0].starts_with("cut.csv:13:3: "), "{}", n[0]);
        assert!(n[0].contains("y = 10 there has 2 digit(s)"), "{}", n[0]);
        assert!(noted(&run(&format!("{text}0.11,2,111.125"))).is_empty());
        assert!(noted(&run(&format!("{cut}\n"))).is_empty());
    }

    // Session 35's refusal of a signal below 1e-140 (`sysid::estimate::SMALLEST_SIGNAL`), for track: an
    // output of about 1e-170 is tracked, but the summary and each JSON line say, in identify's words,
    // that f64 loses its sums of squares and by what factor to rescale it (1e170: the largest |y| here
    // is 4e-170, so -floor(log10 4e-170) = 170); the same record at y of order 1 says nothing of it.
    #[test]
    fn a_tiny_signal_is_said_in_identifys_words() {
        let text = |scale: f64| {
            let mut t = String::from("t,u,y\n");
            for k in 0..300 {
                t.push_str(&format!(
                    "{},{},{:e}\n",
                    k as f64 * 0.01,
                    (k / 7 % 3) as f64 - 1.0,
                    scale * (1.0 + (k % 4) as f64)
                ));
            }
            t
        };
        let options = StreamOptions {
            name: "tiny.csv".into(),
            csv: CsvOptions::default(),
            every: 100,
            restarts: None,
            live: false,
        };
        let run = |scale: f64| {
            let mut tracker = Tracker::new(sysid::online::TrackSettings {
                kind: sysid::ModelKind::Arx,
                ..Default::default()
            })
            .unwrap();
            let mut out = Vec::new();
            let s = track_stream(
                std::io::Cursor::new(text(scale).into_bytes()),
                &mut out,
                &mut tracker,
                &options,
            )
            .unwrap();
            (s, String::from_utf8(out).unwrap())
        };
        let words = "the output y is at most 4.000e-170 in magnitude: at this scale f64 loses the sums of squares";
        let (s, lines) = run(1e-170);
        let said: Vec<_> = s.warnings.iter().filter(|w| w.contains(words)).collect();
        assert_eq!(said.len(), 1, "{:?}", s.warnings);
        assert!(said[0].starts_with("tiny.csv: "), "{}", said[0]);
        assert!(said[0].contains("multiply it by 1e170"), "{}", said[0]);
        assert!(
            lines.lines().count() >= 2 && lines.lines().all(|l| l.contains(words)),
            "{lines}"
        );
        let (s, lines) = run(1.0);
        assert!(
            !s.warnings.iter().any(|w| w.contains("f64 loses")),
            "{:?}",
            s.warnings
        );
        assert!(!lines.contains("f64 loses"));
    }

    // Audit s36 M-3: a followed file that ends (idle time-out) inside its last line ("0.5,0.": the logger
    // stopped mid-line) ends the run with its summary, the 50 finished rows tracked and the unfinished
    // line dropped with a warning; the same bytes read to their end as a finished file (not live) are
    // refused at that line, as before.
    #[test]
    fn a_live_source_ending_inside_its_last_line_drops_it_and_keeps_the_run() {
        let mut text = String::from("t,u,y\n");
        for k in 0..50 {
            text.push_str(&format!(
                "{},{},{}\n",
                k as f64 * 0.01,
                (k % 3) as f64 - 1.0,
                k % 5
            ));
        }
        text.push_str("0.5,0.");
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("live.csv");
        std::fs::write(&path, &text).unwrap();
        let tracker = || {
            Tracker::new(sysid::online::TrackSettings {
                kind: sysid::ModelKind::Arx,
                ..Default::default()
            })
            .unwrap()
        };
        let options = |live: bool| StreamOptions {
            name: "live.csv".into(),
            csv: CsvOptions::default(),
            every: 10,
            restarts: None,
            live,
        };
        let follow = sysid_io::Follow::file(
            &path,
            Some(std::time::Duration::from_millis(50)),
            std::time::Duration::from_millis(5),
        )
        .unwrap();
        let summary = track_stream(
            std::io::BufReader::new(follow),
            &mut Vec::new(),
            &mut tracker(),
            &options(true),
        )
        .unwrap();
        assert_eq!(summary.samples, 50);
        let said: Vec<_> = summary
            .warnings
            .iter()
            .filter(|w| w.contains("ended inside its last line (6 bytes without a line end"))
            .collect();
        assert_eq!(said.len(), 1, "{:?}", summary.warnings);
        let e = track_stream(
            std::io::Cursor::new(text.as_bytes()),
            &mut Vec::new(),
            &mut tracker(),
            &options(false),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("live.csv:52:"), "{e}");
    }
}
