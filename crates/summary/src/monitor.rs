//! One monitoring window of one actuator (the Python `ipa_sysid.fleet`): the identification of the
//! window's record, exactly as `ipa-sysid identify --json` reports it ([`IdentifyReport`]: the same
//! parameters, standard deviations, metrics and warnings) but without the residual analysis, which a
//! fleet row does not carry ([`IdentifyReport::without_residuals`]), and the
//! change points of the online tracker run over the same samples, exactly as `ipa-sysid track` finds
//! them ([`Tracker`]). A fleet is many such windows; the engine that maps them (Dask, Spark) is not
//! this crate's business.

use sysid::data::{NonFinite, Signals};
use sysid::online::{TrackSettings, Tracker};
use sysid::{Dataset, Identification, SysidError};

use crate::IdentifyReport;

/// What to compute on each window.
#[derive(Debug, Clone)]
pub struct WindowSettings {
    /// The identification (`identify`'s flags, checked).
    pub identification: Identification,
    /// The tracker and its change detector (`track`'s flags).
    pub track: TrackSettings,
}

/// The results of one window.
#[derive(Debug, Clone)]
pub struct WindowResult {
    /// The `identify --json` document of the window, its residual analysis not computed.
    pub report: IdentifyReport,
    /// Samples k (0-based, within the window) at which the tracker's detector raised an alarm
    /// (`track`'s change points).
    pub change_points: Vec<usize>,
}

/// Identifies the window `data` and runs the tracker over it.
pub fn window(data: &Dataset, settings: &WindowSettings) -> Result<WindowResult, SysidError> {
    let fit = sysid::identify(data, &settings.identification)?;
    let report = IdentifyReport::without_residuals(
        &fit,
        &settings.identification,
        std::slice::from_ref(data),
    )?;
    let mut tracker = Tracker::new(settings.track)?;
    let mut change_points = Vec::new();
    for (&u, &y) in data.u().iter().zip(data.y()) {
        let step = tracker.push(u, y)?;
        if step.change {
            change_points.push(step.k);
        }
    }
    Ok(WindowResult {
        report,
        change_points,
    })
}

/// Upper bound on the windows of one partition ([`windows`]), checked before anything is allocated.
pub const MAX_PARTITION_WINDOWS: usize = 10_000_000;

/// The name of every window's record in [`partition`] (what a [`WindowFault::Failed`] error calls the
/// record; [`SysidError::render_within`] leaves it out).
pub const WINDOW_RECORD: &str = "the window";

/// One window of a partition of many actuators' records: actuator (`group`) g's `window`-th run of
/// samples, rows `first ..= last` of the partition.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct WindowSpan {
    /// The actuator's position in the partition (0-based; not its identifier).
    pub group: usize,
    /// The window's index within the actuator's rows (0-based).
    pub window: usize,
    /// The window's first row of the partition.
    pub first: usize,
    /// Its last row (inclusive).
    pub last: usize,
}

/// Why a window of a partition was not identified.
#[derive(Debug)]
pub enum WindowFault {
    /// A sample that is not a finite number (found before any identification); its `sample` counts
    /// from the window's first row ([`WindowSpan::first`] + sample is the partition's row).
    NonFinite(NonFinite),
    /// The identification or the tracker failed; the window's record is named [`WINDOW_RECORD`].
    Failed(SysidError),
}

/// The complete windows of a partition whose actuators hold rows `offsets[g] .. offsets[g + 1]`, in
/// order: each actuator's rows cut into consecutive windows of `window` samples, an incomplete last
/// window left out. Refuses offsets that do not run non-decreasing from 0 to `rows`, a `window` below 2,
/// and more than [`MAX_PARTITION_WINDOWS`] windows.
pub fn windows(
    offsets: &[usize],
    rows: usize,
    window: usize,
) -> Result<Vec<WindowSpan>, SysidError> {
    if offsets.first() != Some(&0)
        || offsets.last() != Some(&rows)
        || offsets.windows(2).any(|w| w[1] < w[0])
    {
        return Err(SysidError::Data(format!(
            "offsets: expected non-decreasing row offsets from 0 to {rows} (the number of samples)"
        )));
    }
    if window < 2 {
        return Err(SysidError::Data(format!(
            "window = {window}: expected at least 2 samples"
        )));
    }
    let mut spans = Vec::new();
    for (group, w) in offsets.windows(2).enumerate() {
        let count = (w[1] - w[0]) / window;
        if spans.len() + count > MAX_PARTITION_WINDOWS {
            return Err(SysidError::Data(format!(
                "more than {MAX_PARTITION_WINDOWS} windows in one partition: use smaller partitions"
            )));
        }
        spans.extend((0..count).map(|j| {
            let first = w[0] + j * window;
            WindowSpan {
                group,
                window: j,
                first,
                last: first + window - 1,
            }
        }));
    }
    Ok(spans)
}

/// Every window `spans` of a partition (`u`, `y`: its rows; [`windows`]) identified and tracked
/// ([`window`]), Ts = `ts` (s): one result per span, in order. A window with a sample that is not
/// finite is a [`WindowFault::NonFinite`] naming the signal, the sample within the window and its
/// value; one whose identification fails a [`WindowFault::Failed`]; the other windows go on (a fleet
/// goes on past one bad record). Spans beyond the rows are refused. A stop requested through
/// `settings.identification.cancel` (Python's Ctrl-C) ends the whole partition with
/// [`SysidError::Cancelled`], checked before each window and passed through from inside one.
pub fn partition(
    u: &[f64],
    y: &[f64],
    spans: &[WindowSpan],
    ts: f64,
    settings: &WindowSettings,
) -> Result<Vec<Result<WindowResult, WindowFault>>, SysidError> {
    let rows = u.len().min(y.len());
    if let Some(s) = spans.iter().find(|s| s.first > s.last || s.last >= rows) {
        return Err(SysidError::Data(format!(
            "window rows {}..={} outside the partition's {rows} rows",
            s.first, s.last
        )));
    }
    let stop = &settings.identification.cancel;
    let mut results = Vec::with_capacity(spans.len());
    for s in spans {
        // A window that fails is a fault row (a fleet goes on past one bad record); a stop requested
        // by the caller (`Identification::cancel`) ends the whole partition.
        stop.check()?;
        let (u, y) = (&u[s.first..=s.last], &y[s.first..=s.last]);
        if let Some(fault) = NonFinite::first([("u", u)], y) {
            results.push(Err(WindowFault::NonFinite(fault)));
            continue;
        }
        let signals = Signals {
            u: u.to_vec(),
            y: y.to_vec(),
        };
        match Dataset::new(signals, ts, WINDOW_RECORD).and_then(|d| window(&d, settings)) {
            Err(SysidError::Cancelled) => return Err(SysidError::Cancelled),
            r => results.push(r.map_err(WindowFault::Failed)),
        }
    }
    Ok(results)
}
