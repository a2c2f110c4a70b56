//! `ipa-sysid track`: the recursive estimator on samples as they arrive (standard input, a file being
//! appended, a serial port), one JSON line every `--every` samples; change detection on the prediction
//! errors. The estimator is `sysid::online`; this module opens the source and maps flags, and
//! `track_stream` reads the lines by `identify`'s CSV rules.

use std::io::{BufReader, Write};
use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::Context;
use sysid::online::{DeadzoneStart, DetectorSettings, TrackSettings, Tracker};
use sysid::windup::Windup;
use sysid::{ModelKind, Orders};

use super::common::check_outputs;
use super::track_stream::{track_stream, StreamOptions};

/// Flags of `track`.
#[derive(Debug, clap::Args)]
#[command(group(clap::ArgGroup::new("source").required(true).args(["data", "follow", "serial"])))]
pub struct Args {
    /// CSV stream with a header row (`-`: standard input), read to its end.
    #[arg(long, value_name = "FILE")]
    pub data: Option<PathBuf>,
    /// A CSV file that is still being appended: keeps reading new lines; ends only after
    /// --idle-timeout seconds without a new byte (without it: until stopped).
    #[arg(long, value_name = "FILE")]
    pub follow: Option<PathBuf>,
    /// A serial port (e.g. /dev/ttyUSB0) sending CSV lines (8N1, raw); ends like --follow.
    #[arg(long, value_name = "PATH")]
    pub serial: Option<PathBuf>,
    /// Baud rate of --serial.
    #[arg(long, default_value_t = 115_200)]
    pub baud: u32,
    /// --follow / --serial: stop after this many seconds without new data.
    #[arg(long, value_name = "SECONDS")]
    pub idle_timeout: Option<f64>,
    /// Name of the input column u.
    #[arg(long, default_value = "u", value_name = "NAME")]
    pub u_col: String,
    /// Name of the output column y.
    #[arg(long, default_value = "y", value_name = "NAME")]
    pub y_col: String,
    /// Name of the time column t (optional with --ts: then t = k Ts).
    #[arg(long, default_value = "t", value_name = "NAME")]
    pub t_col: String,
    /// Sampling period Ts in seconds (default: the difference of the first two times). A --ts that
    /// contradicts the time column is used and said once, as `identify` says it.
    #[arg(long, value_name = "SECONDS")]
    pub ts: Option<f64>,
    /// Unit of the time column (Ts and --ts are always in seconds), as `identify`'s.
    #[arg(long, value_enum, default_value = "s")]
    pub time_unit: sysid::data::TimeUnit,
    /// Model structure (as `identify`; `--model` is an alias).
    #[arg(
        long = "structure",
        alias = "model",
        value_name = "STRUCTURE",
        value_enum,
        default_value = "hammerstein"
    )]
    pub model: ModelKind,
    /// na: number of poles.
    #[arg(long, default_value_t = 3)]
    pub na: usize,
    /// nb: number of B coefficients (>= 1 for Hammerstein).
    #[arg(long, default_value_t = 1)]
    pub nb: usize,
    /// nk: input delay in samples.
    #[arg(long, default_value_t = 1)]
    pub nk: usize,
    /// RLS forgetting factor ρ in (0, 1].
    #[arg(long, default_value_t = 1.0)]
    pub forgetting: f64,
    /// RLS initial covariance P(0) = p0 · I (also P after a detected change).
    #[arg(long, default_value_t = 1e6)]
    pub p0: f64,
    /// Covariance-windup protection (as `identify`; default trace here, for long runs).
    #[arg(long, value_enum, default_value = "trace")]
    pub windup: Windup,
    /// Bound on tr P for --windup trace (default: p0 times the number of parameters).
    #[arg(long, value_name = "T")]
    pub max_trace: Option<f64>,
    /// Hammerstein: initial left breakpoint b_l0 (counts, < 0; identify uses the record's largest
    /// negative command).
    #[arg(long, value_name = "COUNTS", default_value_t = DeadzoneStart::PWM.b_l0)]
    pub b_l0: f64,
    /// Hammerstein: initial right breakpoint b_r0 (counts, > 0; identify uses the record's smallest
    /// positive command).
    #[arg(long, value_name = "COUNTS", default_value_t = DeadzoneStart::PWM.b_r0)]
    pub b_r0: f64,
    /// Hammerstein: bound on |b_l|, |b_r| while estimating, counts (identify uses max |u| of the record).
    #[arg(long, value_name = "COUNTS", default_value_t = DeadzoneStart::PWM.limit)]
    pub breakpoint_limit: f64,
    /// Print a JSON line every K samples (and at every detected change).
    #[arg(long, value_name = "K", default_value_t = 100)]
    pub every: usize,
    /// Number of recent prediction errors in pe_rms.
    #[arg(long, value_name = "N", default_value_t = 100)]
    pub pe_window: usize,
    /// Hammerstein: the deadzone guard — the switching functions never use a branch with a slope ≤ 0
    /// or a breakpoint on the wrong side of zero, on which the one-pass estimate can lock. Off by
    /// default, so that with `--windup none` and the record's own start the estimate is exactly
    /// `identify --method rls --passes 1`'s (with track's defaults they differ by rounding: docs/online.md).
    #[arg(long)]
    pub guard: bool,
    /// Off by default, kept so that scripts that turned the guard off keep working.
    #[arg(long, hide = true, conflicts_with = "guard")]
    pub no_guard: bool,
    /// On a detected change restart the covariance P = p0 I (θ̂ kept) so the estimate re-converges on
    /// the changed plant; without it a change is only reported (`change: true`, change points).
    #[arg(long)]
    pub restart_on_change: bool,
    /// No change detection.
    #[arg(long)]
    pub no_detect: bool,
    /// Change detector: samples ignored after the start and after each change (estimator converging).
    #[arg(long, value_name = "N", default_value_t = DetectorSettings::default().warmup)]
    pub detect_warmup: usize,
    /// Change detector: samples over which the error variance σ̂² is calibrated.
    #[arg(long, value_name = "N", default_value_t = DetectorSettings::default().calibration)]
    pub detect_calibration: usize,
    /// Change detector: CUSUM drift ν (> 1) subtracted from ε²/σ̂².
    #[arg(long, value_name = "NU", default_value_t = DetectorSettings::default().drift)]
    pub detect_drift: f64,
    /// Change detector: CUSUM threshold h (docs/online.md gives the false-alarm rates).
    #[arg(long, value_name = "H", default_value_t = DetectorSettings::default().threshold)]
    pub detect_threshold: f64,
    /// Change detector: after calibration the threshold becomes max(H, C × the largest CUSUM value over
    /// the calibration errors), so the unchanged plant's own bursts of error (stick-slip friction) do
    /// not alarm; 0 keeps H alone (docs/online.md).
    #[arg(long, value_name = "C", default_value_t = DetectorSettings::default().excursion_factor)]
    pub detect_excursion_factor: f64,
    /// Write a summary at the end as JSON (final model, samples, change points; `-` for standard
    /// output, where it is one compact line after the per-sample lines, so the stream stays JSON
    /// lines). `--json-summary`, its former name, is still accepted.
    #[arg(long = "json", alias = "json-summary", value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Exit with code 1 when the end summary carries warnings (they are printed either way), without
    /// writing --json (an earlier file there is kept; the lines already streamed stay).
    #[arg(long)]
    pub strict: bool,
}

impl Args {
    /// The tracker these flags describe.
    pub fn settings(&self) -> TrackSettings {
        TrackSettings {
            kind: self.model,
            orders: Orders {
                na: self.na,
                nb: self.nb,
                nk: self.nk,
            },
            forgetting: self.forgetting,
            p0: self.p0,
            windup: self.windup,
            max_trace: self.max_trace,
            start: DeadzoneStart {
                b_l0: self.b_l0,
                b_r0: self.b_r0,
                limit: self.breakpoint_limit,
            },
            pe_window: self.pe_window,
            detector: (!self.no_detect).then_some(DetectorSettings {
                warmup: self.detect_warmup,
                calibration: self.detect_calibration,
                drift: self.detect_drift,
                threshold: self.detect_threshold,
                excursion_factor: self.detect_excursion_factor,
            }),
            guard: self.guard,
            restart_on_change: self.restart_on_change,
        }
    }

    fn idle(&self) -> anyhow::Result<Option<Duration>> {
        self.idle_timeout
            .map(|s| {
                if !(0.0..=MAX_IDLE_S).contains(&s) {
                    anyhow::bail!(sysid::SysidError::setting(
                        sysid::Setting::Other("--idle-timeout"),
                        s,
                        &format!("a number of seconds in 0..={MAX_IDLE_S} (a year)")
                    ));
                }
                Ok(Duration::from_secs_f64(s))
            })
            .transpose()
    }
}

/// The longest `--idle-timeout`, s: a year (a larger one is a typo, and `Duration` overflows near
/// 1.8e19 s).
const MAX_IDLE_S: f64 = 365.0 * 86_400.0;

/// How often a followed file or serial port is polled when no data has come.
const POLL: Duration = Duration::from_millis(20);

/// Refuses a followed file whose first bytes say it is not a record (a model file, a plant
/// configuration, a Parquet file…), in the words of every other reader (audit s27 L-4: `track --data
/// m.json` said "no column named 'u' … the header has: {"). A file that does not exist yet (`--follow`
/// waits for it) or cannot be read is left to the reader's own error; a device or FIFO is not read
/// ahead here (its bytes would be lost to the tracker).
fn check_kind(path: &std::path::Path) -> anyhow::Result<()> {
    use std::io::Read;
    let mut prefix = Vec::with_capacity(4096);
    if let Ok(f) = std::fs::File::open(path) {
        if f.metadata().is_ok_and(|m| m.is_file()) && f.take(4096).read_to_end(&mut prefix).is_ok()
        {
            sysid::data::check_record_kind(&prefix, &path.display().to_string(), "a data file")?;
        }
    }
    Ok(())
}

/// [`check_kind`] on the reader's own first bytes (`--data FILE` or `-`): they are looked at in its
/// buffer and left there, so a file is opened once and standard input or a FIFO loses nothing. A read
/// that fails is left to the reader's own error.
fn peek_kind(reader: &mut dyn std::io::BufRead, name: &str) -> anyhow::Result<()> {
    if let Ok(prefix) = reader.fill_buf() {
        sysid::data::check_record_kind(prefix, name, "a data file")?;
    }
    Ok(())
}

/// Whether standard input is a regular file (`track --data - < FILE`: a finished file, whose last line
/// may end without a line end) rather than a pipe or a terminal (a live logger, whose unfinished last
/// line is dropped when it ends: [`StreamOptions::live`]).
fn stdin_is_a_file() -> bool {
    #[cfg(unix)]
    {
        use std::os::fd::AsFd;
        std::io::stdin()
            .as_fd()
            .try_clone_to_owned()
            .ok()
            .map(std::fs::File::from)
            .and_then(|f| f.metadata().ok())
            .is_some_and(|m| m.is_file())
    }
    #[cfg(not(unix))]
    {
        true
    }
}

/// Runs `track`.
pub fn run(args: Args) -> anyhow::Result<()> {
    // A list of inputs is the other commands' several-input form; the tracker follows one (audit s14
    // L-j: the list was looked up as one column's name).
    if args.u_col.contains(',') {
        anyhow::bail!(sysid::SysidError::setting(
            sysid::Setting::UCol,
            &args.u_col,
            "one input column: track follows a single-input model, one input at a time; run it once \
             per input (--u-col NAME)",
        ));
    }
    let mut tracker = Tracker::new(args.settings())?;
    let idle = args.idle()?;
    let mut inputs = Vec::new();
    let mut restarts = None;
    // Set when a serial port hangs up (audit s32 L-3): the run then ends as at --idle-timeout.
    let hung_up = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let (mut reader, name): (Box<dyn std::io::BufRead>, String) = if let Some(p) = &args.data {
        if p.as_os_str() == "-" {
            (Box::new(std::io::stdin().lock()), "<stdin>".into())
        } else {
            inputs.push(p.as_path());
            let f = std::fs::File::open(p).with_context(|| p.display().to_string())?;
            (
                Box::new(BufReader::with_capacity(1 << 16, f)),
                p.display().to_string(),
            )
        }
    } else if let Some(p) = &args.follow {
        inputs.push(p.as_path());
        check_kind(p)?;
        let shown = p.display().to_string();
        let r = sysid_io::Follow::file(p, idle, POLL)
            .with_context(|| p.display().to_string())?
            .on_restart(move |note| eprintln!("note: {shown}: {note}"));
        restarts = Some(r.restarts());
        (
            Box::new(BufReader::with_capacity(1 << 16, r)),
            p.display().to_string(),
        )
    } else if let Some(p) = &args.serial {
        let path = p.to_string_lossy().into_owned();
        let port = serialport::new(&path, args.baud)
            .timeout(POLL)
            .open()
            .with_context(|| {
                format!("{path}: cannot open the serial port at {} baud", args.baud)
            })?;
        let r = sysid_io::Follow::new(port, idle, POLL);
        let r = HangUp {
            inner: r,
            hung_up: hung_up.clone(),
        };
        (Box::new(BufReader::new(r)), path)
    } else {
        anyhow::bail!(
            "give a source: --data FILE (- for standard input), --follow FILE or --serial PATH"
        );
    };
    check_outputs(&[(&args.json, "--json")], &inputs)?;
    // A followed file, port or standard input ends at the first Ctrl-C (SIGINT or SIGTERM) with its summary and
    // --json, after the line being read (or at the next poll); a second one ends the process
    // (audit s16 L12).
    // Standard input too (audit s36 L-6): `logger | track --data -` is the live example of
    // docs/online.md, and Ctrl-C, sent to the whole pipeline, is how it ends; the logger's end closes
    // the pipe, and the run ends with its summary.
    let from_stdin = args.data.as_ref().is_some_and(|p| p.as_os_str() == "-");
    if args.follow.is_some() || args.serial.is_some() || from_stdin {
        sysid_io::accept_stop();
    }
    if args.data.is_some() {
        // After the output checks: standard input may wait for its first line here.
        peek_kind(&mut reader, &name)?;
    }
    let options = StreamOptions {
        name,
        csv: sysid::data::CsvOptions {
            u_col: args.u_col.clone(),
            y_col: args.y_col.clone(),
            t_col: args.t_col.clone(),
            ts: args.ts,
            time_unit: args.time_unit,
            ..sysid::data::CsvOptions::default()
        },
        every: args.every,
        restarts,
        live: args.follow.is_some() || args.serial.is_some() || (from_stdin && !stdin_is_a_file()),
    };
    let mut out = std::io::BufWriter::new(std::io::stdout().lock());
    let summary = track_stream(reader, &mut out, &mut tracker, &options)?;
    out.flush().context("writing to standard output")?;
    if sysid_io::stop_asked() {
        eprintln!(
            "stopped by a signal (SIGINT or SIGTERM): the summary of the samples read until then"
        );
    }
    if hung_up.load(std::sync::atomic::Ordering::Relaxed) {
        eprintln!(
            "note: {}: the serial port hung up after {} samples (the other end closed it or was \
             unplugged): the summary of the samples read until then",
            options.name, summary.samples
        );
    }
    for w in &summary.warnings {
        eprintln!("warning: {w}");
    }
    eprintln!(
        "{} samples, {} deadzone guard intervention(s), {} change(s) detected{}",
        summary.samples,
        summary.guard_interventions,
        summary.change_points.len(),
        summary
            .change_points
            .iter()
            .map(|c| format!(" at k = {} (t = {} s)", c.k, c.t))
            .collect::<Vec<_>>()
            .join(",")
    );
    let mut json = None;
    if let Some(path) = &args.json {
        // On standard output the summary is one more line of the JSON-lines stream (the last, with
        // `samples` and no `k`), so a line-by-line reader parses every line; in a file it is
        // pretty-printed.
        let pretty = path.as_os_str() != "-";
        let mut text =
            super::common::report_json(&summary, pretty).context("serialising the summary")?;
        text.push('\n');
        json = Some(text);
    }
    let mut outputs: Vec<(&Path, &[u8], &str)> = Vec::new();
    if let (Some(path), Some(text)) = (&args.json, &json) {
        outputs.push((path, text.as_bytes(), "--json"));
    }
    // With --strict and end warnings, --json is not written (an earlier file stays) and the exit code
    // is 1; the lines already streamed stay as they are.
    super::common::write_outputs(&outputs, &inputs, args.strict, summary.warnings.len())
}

/// A serial port's reader whose hang-up (the other end closed, a USB adapter unplugged: EIO, EPIPE or
/// an end of file from the tty) ends the input as `--idle-timeout` does — an end of input, so the run
/// prints its summary and last estimate and exits as it would then — with `hung_up` set for the note
/// that says so (audit s32 L-3: it ended with "Broken pipe" and no summary).
struct HangUp<R> {
    inner: R,
    hung_up: std::sync::Arc<std::sync::atomic::AtomicBool>,
}

impl<R: std::io::Read> std::io::Read for HangUp<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        use std::io::ErrorKind;
        if self.hung_up.load(std::sync::atomic::Ordering::Relaxed) {
            return Ok(0);
        }
        match self.inner.read(buf) {
            Err(e) if is_hang_up(&e) => {
                self.hung_up
                    .store(true, std::sync::atomic::Ordering::Relaxed);
                Ok(0)
            }
            Err(e) if e.kind() == ErrorKind::Interrupted => Err(e),
            other => other,
        }
    }
}

/// True for the errors a tty gives when its other end hangs up: EPIPE, an unexpected end of file, or
/// EIO (errno 5 on Linux and the BSDs/macOS, what a pty's reader gets once its master is closed).
fn is_hang_up(e: &std::io::Error) -> bool {
    use std::io::ErrorKind;
    matches!(e.kind(), ErrorKind::BrokenPipe | ErrorKind::UnexpectedEof)
        || (cfg!(unix) && e.raw_os_error() == Some(5))
}
