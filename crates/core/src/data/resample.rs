//! Time columns in other units (`--time-unit`) and non-uniform records (`--resample TS`).
//!
//! Loggers often write time in milliseconds and skip or repeat samples. `--resample TS` puts such a
//! record on the uniform grid t_j = t_0 + j·Ts (j = 0.., t_j <= t_last) by linear interpolation between
//! the neighbouring samples (MATLAB `resample`/`interp1` with `'linear'`), and the reader says how
//! non-uniform the original was, because interpolation across a long gap invents data.

use serde::{Deserialize, Serialize};

use crate::error::Setting;
use crate::SysidError;

/// The most samples `--resample` makes per measured row: a grid finer than that is interpolation, not
/// data.
pub const MAX_UPSAMPLING: usize = 100;

/// Unit of the time column.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum TimeUnit {
    /// Seconds.
    #[default]
    S,
    /// Milliseconds (10⁻³ s).
    Ms,
    /// Microseconds (10⁻⁶ s).
    Us,
    /// Nanoseconds (10⁻⁹ s): `time.time_ns()` and pandas' int64 timestamps (audit s35 L-9). A time
    /// since 1970 in ns (about 1.7e18) is read as f64, whose spacing there is 256 ns: each time is
    /// rounded by up to 128 ns, which the readers' 0.1 % rule on the steps allows from steps of
    /// 0.26 ms on.
    Ns,
}

impl TimeUnit {
    /// Seconds per unit.
    pub fn seconds(self) -> f64 {
        match self {
            TimeUnit::S => 1.0,
            TimeUnit::Ms => 1e-3,
            TimeUnit::Us => 1e-6,
            TimeUnit::Ns => 1e-9,
        }
    }
}

/// How non-uniform a time column was: its steps in s.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spacing {
    /// Smallest step, s.
    pub min: f64,
    /// Median step, s.
    pub median: f64,
    /// Largest step, s.
    pub max: f64,
    /// Fraction (0..1) of the steps that differ from the median by more than 0.1 %.
    pub irregular: f64,
}

/// The spacing of the strictly increasing times `t` (at least two).
pub fn spacing(t: &[f64]) -> Spacing {
    let mut steps: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    if steps.is_empty() {
        return Spacing {
            min: 0.0,
            median: 0.0,
            max: 0.0,
            irregular: 0.0,
        };
    }
    let n = steps.len();
    let median = *steps.select_nth_unstable_by(n / 2, f64::total_cmp).1;
    let irregular = steps
        .iter()
        .filter(|d| (*d - median).abs() > 1e-3 * median)
        .count() as f64
        / n as f64;
    Spacing {
        min: steps.iter().copied().fold(f64::INFINITY, f64::min),
        median,
        max: steps.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        irregular,
    }
}

/// The spread of a time column's steps in words, "the time steps were 0.01 to 0.268 s (median 0.01 s),
/// 13.5 % of them more than 0.1 % off the median": the one wording of the resample note and of the
/// note of `--ts` over a column that is not uniform ([`super::time_notes`]).
pub fn spacing_words(sp: &Spacing) -> String {
    format!(
        "the time steps were {} to {} s (median {} s), {:.1} % of them more than 0.1 % off the median",
        super::sig6(sp.min),
        super::sig6(sp.max),
        super::sig6(sp.median),
        100.0 * sp.irregular
    )
}

/// The values of the piecewise-linear interpolant through (t_i, s_i) at t_j = t_0 + j·ts, for every j with
/// t_j <= t_last (times strictly increasing, ts > 0). Returns the new samples of each signal in `signals`.
pub fn linear(t: &[f64], signals: &[&[f64]], ts: f64) -> Vec<Vec<f64>> {
    let (Some(&t0), Some(&tl)) = (t.first(), t.last()) else {
        return vec![Vec::new(); signals.len()];
    };
    // A tolerance of 1e-9 Ts keeps the last grid point when t_last is a multiple of Ts up to rounding.
    let m = ((tl - t0) / ts + 1e-9).floor() as usize + 1;
    let mut out: Vec<Vec<f64>> = signals.iter().map(|_| Vec::with_capacity(m)).collect();
    let mut i = 0; // t[i] <= tj < t[i+1]
    for j in 0..m {
        let tj = (t0 + j as f64 * ts).min(tl);
        while i + 2 < t.len() && t[i + 1] <= tj {
            i += 1;
        }
        let (ta, tb) = (t[i], t[(i + 1).min(t.len() - 1)]);
        let w = if tb > ta {
            ((tj - ta) / (tb - ta)).clamp(0.0, 1.0)
        } else {
            0.0
        };
        for (o, s) in out.iter_mut().zip(signals) {
            let (a, b) = (s[i], s[(i + 1).min(s.len() - 1)]);
            o.push(a + w * (b - a));
        }
    }
    out
}

/// A record resampled by [`resample_record`].
#[derive(Debug, Clone, PartialEq)]
pub struct Resampled {
    /// u on the uniform grid.
    pub u: Vec<f64>,
    /// y on the uniform grid.
    pub y: Vec<f64>,
    /// The warning that says how non-uniform the record was.
    pub note: String,
}

/// `u` and `y` sampled at the increasing times `t` (s), resampled onto Ts = `ts` (`--resample`), with the
/// warning that says how non-uniform the record was; `name` names the record in it.
pub fn resample_record(
    t: &[f64],
    u: &[f64],
    y: &[f64],
    ts: f64,
    name: &str,
) -> Result<Resampled, SysidError> {
    super::check_ts_of(Setting::Other("--resample"), ts)?;
    // The grid size, bounded before anything is allocated (a tiny TS over a long record).
    if let (Some(&t0), Some(&tl)) = (t.first(), t.last()) {
        let m = ((tl - t0) / ts).floor() + 1.0;
        if m.is_nan() || m > super::MAX_SAMPLES as f64 {
            return Err(SysidError::setting(
                Setting::Other("--resample"),
                ts,
                &format!(
                    "a sampling period giving at most {} samples over the record's {} s (this one gives {}); \
                     a larger TS",
                    super::MAX_SAMPLES,
                    super::sig6(tl - t0),
                    super::sig6(m)
                ),
            ));
        }
    }
    // A grid far finer than the measurements is interpolation, not data (audit s14 L-d: 7032 rows onto
    // 49.9 million samples, 5.5 GB).
    if let (Some(&t0), Some(&tl)) = (t.first(), t.last()) {
        let m = ((tl - t0) / ts).floor() + 1.0;
        let most = (MAX_UPSAMPLING * t.len()) as f64;
        if m > most {
            return Err(SysidError::setting(
                Setting::Other("--resample"),
                ts,
                &format!(
                    "a sampling period giving at most {MAX_UPSAMPLING} samples per measured row ({} \
                     samples for these {} rows; this one gives {}): the rest would be invented by \
                     interpolation; a larger TS",
                    most,
                    t.len(),
                    super::sig6(m)
                ),
            ));
        }
    }
    let sp = spacing(t);
    let mut out = linear(t, &[u, y], ts).into_iter();
    let (Some(ru), Some(ry)) = (out.next(), out.next()) else {
        return Err(SysidError::Numerical(
            "resampling produced no signal".into(),
        ));
    };
    let sig = super::sig6;
    let note = format!(
        "{name}: resampled {} rows onto {} samples at Ts = {} s by linear interpolation; {}{}",
        u.len(),
        ru.len(),
        sig(ts),
        spacing_words(&sp),
        if sp.max > 2.0 * ts {
            format!(
                "; the largest gap, {} s, is filled with a straight line (invented data)",
                sig(sp.max)
            )
        } else {
            String::new()
        }
    );
    Ok(Resampled { u: ru, y: ry, note })
}
