//! One monitoring window of one actuator (the Python `ipa_sysid.fleet`): the identification of the
//! window's record, exactly as `ipa-sysid identify --json` reports it ([`IdentifyReport`]: the same
//! parameters, standard deviations, metrics and warnings) but without the residual analysis, which a
//! fleet row does not carry ([`IdentifyReport::without_residuals`]), and the
//! change points of the online tracker run over the same samples, exactly as `ipa-sysid track` finds
//! them ([`Tracker`]). A fleet is many such windows; the engine that maps them (Dask, Spark) is not
//! this crate's business.

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
