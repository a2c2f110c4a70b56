//! Online tracking (`ipa-sysid track`): the recursive estimator run sample by sample on data as they
//! arrive, with a change detector on its prediction errors.
//!
//! [`Tracker::push`] does, for sample k (counted from 0), exactly what the first pass of
//! [`RecursiveLeastSquares`](crate::RecursiveLeastSquares) (`identify --method rls --passes 1`) does at
//! row k: no regression before k0 = max(na, nk + nb − 1); for a Hammerstein model at k > k0 the
//! deadzone of the switching functions and of x̂ is taken from the latest θ̂ (breakpoints clamped to
//! ±limit, the start deadzone while both slopes are 0), φ(k) is filled by [`Structure::fill_row`] and
//! one RLS update (paper eqs. 9–12) is made by the same estimator type `identify` chooses (plain RLS for
//! `--windup none`, [`RobustRls`] otherwise). The only input `identify` takes from the whole record is
//! the start of the deadzone (the largest negative and smallest positive command, and max |u| as the
//! clamp); online these are settings, [`DeadzoneStart`], whose default (−1, 1, 255) suits integer PWM
//! commands. With the defaults (no deadzone guard, no restart on a change) and the start `identify`
//! uses ([`DeadzoneStart::from_record`], or the default on integer PWM commands) the estimate equals
//! `identify`'s bit for bit. The guard ([`TrackSettings::guard`], opt-in) keeps the switching functions
//! from using a deadzone branch with a slope ≤ 0 or a breakpoint on the wrong side of zero, on which
//! the one-pass estimate can otherwise lock (docs/online.md).
//!
//! # Change detection
//!
//! The a-priori errors ε(k) feed Page's CUSUM on z(k) = ε(k)²/σ̂² ([`ipa_embedded::cusum::Cusum`]; its
//! module documents the average run lengths): after a warm-up of [`DetectorSettings::warmup`] samples
//! (the estimator converging) σ̂² is the mean of ε² over the next [`DetectorSettings::calibration`]
//! samples, then g(k) = max(0, g(k−1) + z(k) − ν) raises an alarm when g > h. On an alarm the tracker
//! records a change point, with [`TrackSettings::restart_on_change`] restarts the covariance P = p0 · I
//! (θ̂ kept, so the estimator re-converges on the new valve), and starts a new detector (warm-up and
//! calibration again, because the noise level of the new valve may differ). No second alarm can come
//! during that warm-up and calibration. Without the restart (the default) the alarm changes nothing in
//! the estimate.

use std::io::{BufRead, Write};

use serde::Serialize;

use crate::rls::{RecursiveUpdate, Rls};
use crate::rls_ud::{RlsForm, RobustRls};
use crate::summary::{poles, Pole};
use crate::windup::Windup;
use ipa_embedded::cusum::{Cusum, CusumStatus};
use sysid_core::error::ColumnHint;
use sysid_core::param::{deadzone_from_theta, Layout, Parameterisation, ZERO_DEADZONE};
use sysid_core::{Deadzone, Model, ModelKind, Orders, Setting, Structure, SysidError};

/// The deadzone a Hammerstein tracker starts from (unit slopes) and the clamp on breakpoint estimates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeadzoneStart {
    /// b_l0: initial left breakpoint (counts, < 0).
    pub b_l0: f64,
    /// b_r0: initial right breakpoint (counts, > 0).
    pub b_r0: f64,
    /// Bound on |b̂_l|, |b̂_r| while estimating (counts, > 0).
    pub limit: f64,
}

impl DeadzoneStart {
    /// The online start for integer PWM commands: b_l0 = −1, b_r0 = 1, limit = 255 counts. Every
    /// nonzero integer command switches its branch on, as with `identify`'s start.
    pub const PWM: DeadzoneStart = DeadzoneStart {
        b_l0: -1.0,
        b_r0: 1.0,
        limit: 255.0,
    };

    /// The start `identify` takes from a whole record of commands: the largest u < 0, the smallest
    /// u > 0 and max |u|. `None` when the record is not two-sided (`identify` then drops a branch, which
    /// a tracker cannot know in advance).
    pub fn from_record(u: &[f64]) -> Option<Self> {
        let max_neg = u.iter().copied().filter(|&v| v < 0.0).reduce(f64::max)?;
        let min_pos = u.iter().copied().filter(|&v| v > 0.0).reduce(f64::min)?;
        let limit = u.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        Some(DeadzoneStart {
            b_l0: max_neg,
            b_r0: min_pos,
            limit,
        })
    }

    fn deadzone(&self) -> Deadzone {
        Deadzone {
            b_l: self.b_l0,
            b_r: self.b_r0,
            m_l: 1.0,
            m_r: 1.0,
        }
    }
}

/// Settings of the change detector (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DetectorSettings {
    /// Samples (after k0) whose errors are ignored while the estimator converges.
    pub warmup: usize,
    /// Samples over which σ̂² is the mean of ε² (≥ 1).
    pub calibration: usize,
    /// ν > 1: the drift subtracted from each z(k) (E z = 1 without change).
    pub drift: f64,
    /// h > 0: alarm when g(k) > h (the least threshold; see `excursion_factor`).
    pub threshold: f64,
    /// c ≥ 0: after calibration the CUSUM is replayed over the calibration errors themselves and the
    /// threshold becomes max(h, c · the largest g(k) seen there). Errors of a model that does not
    /// describe the plant (a cylinder with stick-slip friction, for a deadzone + ARX model) are
    /// heavy-tailed — large while the piston moves, tiny while it sticks — and a fixed h then alarms after
    /// every calibration; raising h to what the unchanged plant itself produces keeps alarms for changes
    /// the calibration data have not seen. 0: the fixed h alone.
    pub excursion_factor: f64,
}

impl Default for DetectorSettings {
    /// Warm-up 500, calibration 2000 samples, ν = 3, h = 60. For white Gaussian errors the average run
    /// length without change is ≈ 3.6 · 10¹³ samples (h = 30, the firmware default of
    /// [`ipa_embedded::cusum`], gives 2.7 · 10⁷); the higher threshold is for the coloured errors of a
    /// model fitted to data with output noise, where h = 30 raised 6 false alarms in 500 000 samples
    /// and h = 60 none in 2 000 000 (docs/online.md).
    fn default() -> Self {
        DetectorSettings {
            warmup: 500,
            calibration: 2000,
            drift: 3.0,
            threshold: 60.0,
            excursion_factor: 4.0,
        }
    }
}

impl DetectorSettings {
    fn detector(&self) -> Result<Detector, SysidError> {
        let valid = Cusum::<f64>::new(self.warmup, self.calibration, self.drift, self.threshold)
            .is_ok()
            && self.excursion_factor.is_finite()
            && self.excursion_factor >= 0.0;
        if !valid {
            return Err(SysidError::setting(
                Setting::Other(
                    "--detect-calibration/--detect-drift/--detect-threshold/--detect-excursion-factor",
                ),
                format!(
                    "calibration {}, drift {}, threshold {}, excursion factor {}",
                    self.calibration, self.drift, self.threshold, self.excursion_factor
                ),
                "calibration >= 1 sample, drift > 1, a positive, finite threshold and a factor >= 0",
            ));
        }
        Ok(Detector {
            settings: *self,
            seen: 0,
            calibration: Vec::with_capacity(self.calibration),
            cusum: None,
            threshold: self.threshold,
        })
    }
}

/// Page's CUSUM ([`ipa_embedded::cusum::Cusum`]) with σ̂² and the threshold taken from a calibration
/// window of the errors themselves ([`DetectorSettings::excursion_factor`]).
#[derive(Debug, Clone)]
struct Detector {
    settings: DetectorSettings,
    /// Errors seen since this detector started.
    seen: usize,
    /// The calibration errors, until the CUSUM starts.
    calibration: Vec<f64>,
    /// Monitoring once calibrated.
    cusum: Option<Cusum<f64>>,
    /// The threshold in use: h, raised after calibration.
    threshold: f64,
}

impl Detector {
    /// Feeds ε(k) (finite); true on an alarm.
    fn update(&mut self, eps: f64) -> bool {
        self.seen += 1;
        if let Some(c) = &mut self.cusum {
            return matches!(c.update(eps), Ok(CusumStatus::Alarm(_)));
        }
        if self.seen <= self.settings.warmup {
            return false;
        }
        self.calibration.push(eps);
        if self.calibration.len() < self.settings.calibration {
            return false;
        }
        let n = self.calibration.len() as f64;
        let variance = self.calibration.iter().map(|e| e * e).sum::<f64>() / n;
        let (nu, h) = (self.settings.drift, self.settings.threshold);
        // The statistic over the calibration errors: what the unchanged plant produces.
        let largest = (variance > 0.0).then(|| {
            let mut g = 0.0_f64;
            self.calibration.iter().fold(0.0_f64, |m, e| {
                g = (g + e * e / variance - nu).max(0.0);
                m.max(g)
            })
        });
        let threshold = largest.map_or(h, |m| h.max(self.settings.excursion_factor * m));
        match Cusum::with_variance(variance, nu, threshold) {
            Ok(c) => {
                self.cusum = Some(c);
                self.threshold = threshold;
                self.calibration = Vec::new();
            }
            // σ̂² = 0 (a noise-free record): keep calibrating, so never alarm.
            Err(_) => self.calibration.clear(),
        }
        false
    }

    /// g(k) and σ̂² once calibrated.
    fn state(&self) -> Option<(f64, f64)> {
        let c = self.cusum.as_ref()?;
        c.variance().map(|v| (c.statistic(), v))
    }
}

/// Settings of a [`Tracker`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackSettings {
    /// ARX or Hammerstein (no offset).
    pub kind: ModelKind,
    /// na, nb, nk.
    pub orders: Orders,
    /// ρ ∈ (0, 1]: forgetting factor.
    pub forgetting: f64,
    /// P(0) = p0 · I, and P after a detected change.
    pub p0: f64,
    /// Covariance-windup protection (`identify --windup`).
    pub windup: Windup,
    /// Bound T on tr P for [`Windup::Trace`]; `None`: p0 times the number of parameters.
    pub max_trace: Option<f64>,
    /// Hammerstein: the start deadzone and breakpoint clamp.
    pub start: DeadzoneStart,
    /// Number of recent prediction errors in [`Tracker::pe_rms`] (≥ 1).
    pub pe_window: usize,
    /// The change detector; `None`: no detection.
    pub detector: Option<DetectorSettings>,
    /// Hammerstein: the switching functions and x̂ never use a deadzone branch with a slope ≤ 0 or a
    /// breakpoint on the wrong side of zero (b_l > 0, b_r < 0); the last plausible branch is kept
    /// instead. Without it (`false`, the default) every sample is exactly `identify`'s first pass.
    pub guard: bool,
    /// On a detected change restart the covariance P = p0 · I (θ̂ kept), so the estimate re-converges on
    /// the changed plant with full gain. Without it (`false`, the default) a change is only reported and
    /// the estimate stays exactly `identify`'s first pass.
    pub restart_on_change: bool,
}

impl Default for TrackSettings {
    /// The paper's structure (Hammerstein, na = 3, nb = 1, nk = 1), ρ = 1, p0 = 10⁶, trace windup
    /// guard, [`DeadzoneStart::PWM`], a window of 100 errors, the default detector reporting changes
    /// (no restart), no deadzone guard: with `windup: Windup::None` the estimate is then exactly
    /// `identify --method rls --passes 1`'s, whatever the detector reports.
    fn default() -> Self {
        TrackSettings {
            kind: ModelKind::Hammerstein,
            orders: Orders::PAPER,
            forgetting: 1.0,
            p0: 1e6,
            windup: Windup::Trace,
            max_trace: None,
            start: DeadzoneStart::PWM,
            pe_window: 100,
            detector: Some(DetectorSettings::default()),
            guard: false,
            restart_on_change: false,
        }
    }
}

/// Approximate standard deviations of a tracker's deadzone estimate ([`Tracker::deadzone_sd`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DeadzoneSd {
    /// Of b̂_l (counts).
    pub b_l: f64,
    /// Of b̂_r (counts).
    pub b_r: f64,
    /// Of m̂_l.
    pub m_l: f64,
    /// Of m̂_r.
    pub m_r: f64,
}

/// What [`Tracker::push`] did with one sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Step {
    /// The sample index k (0-based).
    pub k: usize,
    /// The a-priori prediction error ε(k) = y(k) − φᵀ(k) θ̂(k−1) (mm); `None` before k0.
    pub error: Option<f64>,
    /// The detector raised an alarm at this sample (P was restarted).
    pub change: bool,
}

/// The recursive estimator run sample by sample, with a change detector.
pub struct Tracker {
    settings: TrackSettings,
    structure: Structure,
    key: Parameterisation,
    est: Box<dyn RecursiveUpdate>,
    /// u and y of the last samples; the newest at the end (at most 2 (k0 + 1) kept).
    u: Vec<f64>,
    y: Vec<f64>,
    row: Vec<f64>,
    dz: Deadzone,
    k: usize,
    k0: usize,
    /// Regression updates since the last covariance (re)start.
    updates: usize,
    /// Regression updates in all (the next slot of the ring `errors`).
    updates_total: usize,
    /// The last `pe_window` a-priori errors (a ring).
    errors: Vec<f64>,
    detector: Option<Detector>,
    changes: Vec<usize>,
    guard_hits: usize,
}

/// The recursive estimator `identify --method rls` uses for these settings: the plain RLS for the
/// standard form without windup protection, [`RobustRls`] otherwise.
pub(crate) fn recursive_estimator(
    n_params: usize,
    forgetting: f64,
    p0: f64,
    form: RlsForm,
    windup: Windup,
    max_trace: Option<f64>,
) -> Result<Box<dyn RecursiveUpdate>, SysidError> {
    Ok(if form == RlsForm::Standard && windup == Windup::None {
        Box::new(Rls::new(n_params, forgetting, p0)?)
    } else {
        Box::new(RobustRls::new(
            n_params, forgetting, p0, form, windup, max_trace,
        )?)
    })
}

impl Tracker {
    /// A tracker; errors name the setting out of range.
    pub fn new(settings: TrackSettings) -> Result<Self, SysidError> {
        let structure = Structure {
            kind: settings.kind,
            orders: settings.orders,
            offset: false,
        };
        if settings.kind == ModelKind::Hammerstein {
            if settings.orders.nb == 0 {
                return Err(SysidError::setting(
                    Setting::Nb,
                    0,
                    "nb >= 1 for a Hammerstein model (b1 = 1 is its key term)",
                ));
            }
            let s = settings.start;
            if !(s.b_l0.is_finite() && s.b_l0 < 0.0 && s.b_r0.is_finite() && s.b_r0 > 0.0) {
                return Err(SysidError::setting(
                    Setting::Other("--b-l0/--b-r0"),
                    format!("{}, {}", s.b_l0, s.b_r0),
                    "finite breakpoints b_l0 < 0 < b_r0",
                ));
            }
            if !(s.limit.is_finite() && s.limit > 0.0) {
                return Err(SysidError::setting(
                    Setting::Other("--breakpoint-limit"),
                    s.limit,
                    "a positive, finite bound on |b_l|, |b_r|",
                ));
            }
        }
        if settings.pe_window == 0 {
            return Err(SysidError::setting(
                Setting::Other("--pe-window"),
                0,
                "at least 1 sample",
            ));
        }
        let detector = settings.detector.map(|d| d.detector()).transpose()?;
        let n = structure.n_params();
        let est = recursive_estimator(
            n,
            settings.forgetting,
            settings.p0,
            RlsForm::Standard,
            settings.windup,
            settings.max_trace,
        )?;
        let k0 = settings.orders.k0();
        Ok(Tracker {
            structure,
            key: Parameterisation::new(structure, Layout::KeyTerm),
            est,
            u: Vec::with_capacity(2 * (k0 + 1)),
            y: Vec::with_capacity(2 * (k0 + 1)),
            row: vec![0.0; n],
            dz: if settings.kind == ModelKind::Hammerstein {
                settings.start.deadzone()
            } else {
                ZERO_DEADZONE
            },
            k: 0,
            k0,
            updates: 0,
            updates_total: 0,
            errors: Vec::with_capacity(settings.pe_window),
            detector,
            changes: Vec::new(),
            guard_hits: 0,
            settings,
        })
    }

    /// The settings.
    pub fn settings(&self) -> &TrackSettings {
        &self.settings
    }

    /// Samples pushed so far.
    pub fn samples(&self) -> usize {
        self.k
    }

    /// k0: the first sample with a regression update.
    pub fn k0(&self) -> usize {
        self.k0
    }

    /// Updates of θ̂ since the start or the last covariance restart (a detected change with
    /// [`TrackSettings::restart_on_change`]).
    pub fn updates_since_restart(&self) -> usize {
        self.updates
    }

    /// The samples at which a change was detected.
    pub fn change_points(&self) -> &[usize] {
        &self.changes
    }

    /// θ̂ in the key-term layout ([`Structure::theta_names`]).
    pub fn theta(&self) -> &[f64] {
        self.est.theta()
    }

    /// Processes sample k: u(k) (counts) and y(k) (mm), both finite.
    pub fn push(&mut self, u: f64, y: f64) -> Result<Step, SysidError> {
        let k = self.k;
        if !(u.is_finite() && y.is_finite()) {
            return Err(SysidError::Numerical(format!(
                "sample {k}: u = {u}, y = {y} is not finite"
            )));
        }
        let keep = self.k0 + 1;
        if self.u.len() == 2 * keep {
            self.u.copy_within(keep.., 0);
            self.y.copy_within(keep.., 0);
            self.u.truncate(keep);
            self.y.truncate(keep);
        }
        self.u.push(u);
        self.y.push(y);
        self.k += 1;
        if k < self.k0 {
            return Ok(Step {
                k,
                error: None,
                change: false,
            });
        }
        let hammer = self.structure.kind == ModelKind::Hammerstein;
        if hammer && k > self.k0 {
            let theta = self.est.theta();
            let dz = if theta[0] == 0.0 && theta[2] == 0.0 {
                self.settings.start.deadzone()
            } else {
                deadzone_from_theta(theta, self.dz, self.settings.start.limit)
            };
            self.dz = if self.settings.guard {
                self.guarded(dz)
            } else {
                dz
            };
        }
        let last = self.u.len() - 1;
        self.structure
            .fill_row(&self.u, &self.y, last, &self.dz, &mut self.row);
        let eps = self.est.update(&self.row, y, k)?;
        self.updates += 1;
        if self.errors.len() < self.settings.pe_window {
            self.errors.push(eps);
        } else {
            self.errors[self.updates_total % self.settings.pe_window] = eps;
        }
        self.updates_total += 1;
        let mut change = false;
        if let Some(d) = &mut self.detector {
            // ε is finite: the update checked it.
            change = d.update(eps);
        }
        if change {
            self.changes.push(k);
            if self.settings.restart_on_change {
                self.est.restart_covariance(self.settings.p0);
                self.updates = 0;
            }
            self.detector = self.settings.detector.map(|d| d.detector()).transpose()?;
        }
        Ok(Step {
            k,
            error: Some(eps),
            change,
        })
    }

    /// The deadzone guard: a branch of `dz` with a slope ≤ 0 or its breakpoint on the wrong side of zero
    /// is replaced by that branch of the deadzone in use (counted in [`Tracker::guard_interventions`]).
    fn guarded(&mut self, mut dz: Deadzone) -> Deadzone {
        let mut hit = false;
        if !(dz.m_r > 0.0 && dz.b_r >= 0.0) {
            (dz.m_r, dz.b_r) = (self.dz.m_r, self.dz.b_r);
            hit = true;
        }
        if !(dz.m_l > 0.0 && dz.b_l <= 0.0) {
            (dz.m_l, dz.b_l) = (self.dz.m_l, self.dz.b_l);
            hit = true;
        }
        self.guard_hits += usize::from(hit);
        dz
    }

    /// Samples at which the deadzone guard replaced an implausible branch of the estimate.
    pub fn guard_interventions(&self) -> usize {
        self.guard_hits
    }

    /// RMS of the last [`TrackSettings::pe_window`] a-priori prediction errors (mm); `None` before k0.
    pub fn pe_rms(&self) -> Option<f64> {
        if self.errors.is_empty() {
            return None;
        }
        let ss: f64 = self.errors.iter().map(|e| e * e).sum();
        Some((ss / self.errors.len() as f64).sqrt())
    }

    /// The detector's statistic g(k) and σ̂² (mm²); `None` while warming up or calibrating, or without
    /// a detector.
    pub fn detector_state(&self) -> Option<(f64, f64)> {
        self.detector.as_ref()?.state()
    }

    /// The detector's threshold in use: h, or after calibration max(h, c · the largest g(k) over the
    /// calibration errors) ([`DetectorSettings::excursion_factor`]); `None` without a detector.
    pub fn detector_threshold(&self) -> Option<f64> {
        self.detector.as_ref().map(|d| d.threshold)
    }

    /// Standard deviations of the current deadzone estimate (Hammerstein trackers; `None` for ARX or
    /// before the first update), from σ̂² P with σ̂ = max([`Tracker::pe_rms`], `sigma_floor_mm`).
    ///
    /// With the key-term layout θ = [m_r, m_r b_r, m_l, m_l b_l, …] the slopes are entries of θ and
    /// the breakpoints ratios, whose variance is taken to first order (the delta method):
    /// b_r = θ₁/θ₀, var b̂_r ≈ (P₁₁ − 2 b_r P₀₁ + b_r² P₀₀) σ̂² / θ₀² (and b_l from θ₂, θ₃). A slope
    /// estimate of 0 gives an infinite breakpoint deviation. The floor keeps a run of near-zero errors
    /// (a piston stuck at its set-point, the encoder not moving) from making a poorly excited
    /// estimate look certain: P, not the error level, then carries the lack of excitation.
    ///
    /// Measured against the spread over 40 independent records of the paper's model
    /// (`crates/sysid/tests/online_track.rs`): the breakpoint deviations agree within the sampling error
    /// (spread/prediction 1.0–1.3); the slope deviations are optimistic by a factor ≈ 3.4 at 20 000
    /// samples (6.5 at 3000), because the one-pass estimate keeps the error of its first samples, made
    /// with a deadzone still far from the truth. Closed-loop data with a model that does not fit the
    /// plant (friction) make both optimistic: a small deviation is necessary, not sufficient, for trust.
    pub fn deadzone_sd(&self, sigma_floor_mm: f64) -> Option<DeadzoneSd> {
        if self.structure.kind != ModelKind::Hammerstein || self.updates_total == 0 {
            return None;
        }
        let sigma = self.pe_rms()?.max(sigma_floor_mm);
        let s2 = sigma * sigma;
        let p = self.est.covariance();
        let th = self.est.theta();
        let var = |i: usize| p[(i, i)].max(0.0) * s2;
        let ratio_sd = |s: usize, n: usize| {
            let m = th[s];
            let b = th[n] / m;
            let v = (p[(n, n)] - 2.0 * b * p[(s, n)] + b * b * p[(s, s)]) * s2 / (m * m);
            if v.is_finite() {
                v.max(0.0).sqrt()
            } else {
                f64::INFINITY
            }
        };
        Some(DeadzoneSd {
            m_r: var(0).sqrt(),
            b_r: ratio_sd(0, 1),
            m_l: var(2).sqrt(),
            b_l: ratio_sd(2, 3),
        })
    }

    /// The current estimate as a model with sampling period `ts_s` (s).
    pub fn model(&self, ts_s: f64) -> Result<Model, SysidError> {
        self.key.model_of(self.est.theta(), ts_s)
    }

    /// Reasons not to trust the current estimate or the `change` flag yet, in words.
    pub fn warnings(&self, model: &Model) -> Vec<String> {
        let mut w = Vec::new();
        let n = self.structure.n_params();
        if self.updates < 10 * n {
            w.push(format!(
                "only {} update(s) since the {} for {n} parameters: the estimate is still converging",
                self.updates,
                if self.changes.is_empty() {
                    "start"
                } else {
                    "last detected change"
                }
            ));
        }
        if self.detector.is_some() && self.detector_state().is_none() {
            w.push(
                "the change detector is warming up or calibrating: a change cannot be flagged yet"
                    .to_string(),
            );
        }
        if !model.is_stable() {
            w.push("the current model is unstable (a pole on or outside the unit circle)".into());
        }
        if let Some(d) = model.deadzone() {
            if !(d.m_r > 0.0 && d.m_l > 0.0 && d.b_l <= 0.0 && d.b_r >= 0.0) {
                w.push(format!(
                    "the deadzone estimate is implausible (b_l = {}, b_r = {}, m_l = {}, m_r = {}: a slope <= 0 \
                     or a breakpoint on the wrong side of zero){}",
                    d.b_l,
                    d.b_r,
                    d.m_l,
                    d.m_r,
                    if self.settings.guard {
                        "; the switching functions use the last plausible branch"
                    } else {
                        ""
                    }
                ));
            }
        }
        w
    }
}

/// Where the columns of a streamed CSV are, and how often to report.
#[derive(Debug, Clone, PartialEq)]
pub struct StreamOptions {
    /// The source's name in messages (`<stdin>`, a path).
    pub name: String,
    /// Column of u.
    pub u_col: String,
    /// Column of y.
    pub y_col: String,
    /// Column of t (s); optional when `ts` is given (then t = k Ts).
    pub t_col: String,
    /// Sampling period Ts (s); `None`: the difference of the first two times.
    pub ts: Option<f64>,
    /// Print a line every `every` samples (≥ 1), and at every detected change.
    pub every: usize,
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
    /// All poles inside the unit circle.
    pub stable: bool,
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
}

/// The end of a `track` run (`--json-summary`).
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
    /// All poles inside the unit circle.
    pub stable: Option<bool>,
    /// RMS of the last prediction errors (mm).
    pub pe_rms: Option<f64>,
    /// Detected changes.
    pub change_points: Vec<ChangePoint>,
    /// The CUSUM threshold in use at the end ([`Tracker::detector_threshold`]; `None` without a detector).
    pub detector_threshold: Option<f64>,
    /// Samples at which the deadzone guard replaced an implausible branch ([`TrackSettings::guard`]).
    pub guard_interventions: usize,
    /// Reasons not to trust the final model, in words.
    pub warnings: Vec<String>,
}

/// Which fields of a line hold u, y and t.
#[derive(Debug, Clone, Copy)]
struct Columns {
    u: usize,
    y: usize,
    t: Option<usize>,
}

impl Columns {
    /// The columns named in the header `line` (comma-separated names, optionally quoted, a UTF-8
    /// byte-order mark allowed); also returns the names.
    fn of_header(
        line: &[u8],
        o: &StreamOptions,
        line_no: usize,
    ) -> Result<(Self, Vec<String>), SysidError> {
        let line = line.strip_prefix(b"\xef\xbb\xbf").unwrap_or(line);
        let text = std::str::from_utf8(line).map_err(|e| SysidError::Parse {
            file: o.name.clone(),
            line: line_no,
            column: e.valid_up_to() + 1,
            message: "the header is not UTF-8 text; expected a header such as t,u,y".into(),
        })?;
        let header: Vec<String> = text
            .split(',')
            .map(|h| {
                let h = h.trim();
                h.strip_prefix('"')
                    .and_then(|x| x.strip_suffix('"'))
                    .map_or(h, str::trim)
                    .to_string()
            })
            .collect();
        let find = |col: &str, setting: Setting| {
            header.iter().position(|h| h == col).ok_or_else(|| {
                let hint = if header.iter().all(|h| h.parse::<f64>().is_ok()) {
                    Some(ColumnHint::NoHeader)
                } else {
                    header
                        .iter()
                        .find(|h| h.eq_ignore_ascii_case(col))
                        .map(|h| ColumnHint::Case(h.clone()))
                };
                SysidError::MissingColumn {
                    file: o.name.clone(),
                    column: col.to_string(),
                    setting,
                    header: header.clone(),
                    hint,
                }
            })
        };
        let u = find(&o.u_col, Setting::UCol)?;
        let y = find(&o.y_col, Setting::YCol)?;
        let t = match find(&o.t_col, Setting::TCol) {
            Ok(t) => Some(t),
            Err(_) if o.ts.is_some() => None,
            Err(e) => return Err(e),
        };
        Ok((Columns { u, y, t }, header))
    }

    /// u, y and t (when there is a t column) of a data line.
    fn parse(
        &self,
        line: &[u8],
        line_no: usize,
        name: &str,
        header: &[String],
    ) -> Result<(f64, f64, f64), SysidError> {
        let mut out = [f64::NAN; 3];
        let wanted = [Some(self.u), Some(self.y), self.t];
        let last = wanted.iter().flatten().copied().max().unwrap_or(0);
        let mut found = 0;
        for (i, field) in line.split(|&b| b == b',').enumerate().take(last + 1) {
            found = i + 1;
            for (slot, w) in out.iter_mut().zip(wanted) {
                if w == Some(i) {
                    *slot = parse_field(field).ok_or_else(|| {
                        let cname = header.get(i).map_or("?", String::as_str);
                        SysidError::Parse {
                            file: name.to_string(),
                            line: line_no,
                            column: i + 1,
                            message: format!(
                                "'{}' in column '{cname}' is not a finite number; expected a decimal \
                                 number such as -1.5 or 2e-3",
                                String::from_utf8_lossy(field).trim()
                            ),
                        }
                    })?;
                }
            }
        }
        if found <= last {
            return Err(SysidError::Parse {
                file: name.to_string(),
                line: line_no,
                column: found + 1,
                message: format!(
                    "the line has only {found} field(s); expected {} (the header's columns)",
                    header.len()
                ),
            });
        }
        Ok((out[0], out[1], out[2]))
    }
}

/// A finite f64 from a CSV field (surrounding spaces and quotes allowed).
#[inline]
fn parse_field(field: &[u8]) -> Option<f64> {
    let s = std::str::from_utf8(field).ok()?.trim();
    let s = s
        .strip_prefix('"')
        .and_then(|x| x.strip_suffix('"'))
        .map_or(s, str::trim);
    s.parse::<f64>().ok().filter(|v| v.is_finite())
}

/// Runs `tracker` over CSV lines from `input` (a header row, then `t,u,y` rows; blank lines skipped),
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
    if let Some(ts) = options.ts {
        if !(ts.is_finite() && ts > 0.0) {
            return Err(SysidError::setting(
                Setting::Ts,
                ts,
                "a positive sampling period in seconds",
            ));
        }
    }
    let io_err = |e: std::io::Error| SysidError::Io {
        path: options.name.clone().into(),
        source: e,
    };
    let write_err = |e: std::io::Error| SysidError::Io {
        path: "<output>".into(),
        source: e,
    };
    let mut buf = Vec::with_capacity(256);
    let mut line_no = 0;
    let mut columns = None;
    let mut header = Vec::new();
    let mut ts = options.ts;
    let mut t0 = None;
    let mut t_last = None;
    let mut pending_change = false;
    let mut change_points = Vec::new();
    // Time that jumps (samples missing, a clock reset forwards): warnings for the next line and the end.
    let (mut time_jumps, mut new_time_warnings, mut time_warnings) =
        (0usize, Vec::new(), Vec::new());
    loop {
        buf.clear();
        if input.read_until(b'\n', &mut buf).map_err(io_err)? == 0 {
            break;
        }
        line_no += 1;
        let mut line = buf.as_slice();
        while let [rest @ .., b'\n' | b'\r'] = line {
            line = rest;
        }
        if line.iter().all(u8::is_ascii_whitespace) {
            continue;
        }
        let Some(cols) = columns else {
            let (c, names) = Columns::of_header(line, options, line_no)?;
            header = names;
            columns = Some(c);
            continue;
        };
        let (u, y, t_read) = cols.parse(line, line_no, &options.name, &header)?;
        let k = tracker.samples();
        let t = match (cols.t, ts) {
            (Some(_), _) => t_read,
            (None, Some(ts)) => k as f64 * ts,
            (None, None) => f64::NAN, // not reached: a missing t column needs `ts`
        };
        match (ts, t0) {
            (None, None) => t0 = Some(t),
            (None, Some(first)) => {
                let d = t - first;
                if !(d.is_finite() && d > 0.0) {
                    return Err(SysidError::Parse {
                        file: options.name.clone(),
                        line: line_no,
                        column: cols.t.map_or(1, |c| c + 1),
                        message: format!(
                            "t = {t} after t = {first}: the time must increase (or give --ts)"
                        ),
                    });
                }
                ts = Some(d);
            }
            (Some(ts), _) => {
                if let (Some(tc), Some(prev)) = (cols.t, t_last) {
                    if let Some(w) = check_time_step(prev, t, ts, line_no, tc, &options.name)? {
                        time_jumps += 1;
                        if time_jumps <= 10 {
                            new_time_warnings.push(w);
                        }
                    }
                }
            }
        }
        t_last = Some(t);
        let step = tracker.push(u, y).map_err(|e| match e {
            SysidError::Numerical(m) => {
                SysidError::Numerical(format!("{}:{line_no}: {m}", options.name))
            }
            e => e,
        })?;
        if step.change {
            change_points.push(ChangePoint { k, t });
            pending_change = true;
        }
        if step.error.is_some() && (step.change || (k + 1) % options.every == 0) {
            if let Some(ts) = ts {
                let mut line = track_line(tracker, k, t, ts, pending_change)?;
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
    if columns.is_none() {
        return Err(SysidError::File {
            file: options.name.clone(),
            message: "no header row arrived; expected a header such as t,u,y and data rows".into(),
        });
    }
    let mut summary = summary(tracker, ts, t_last, change_points)?;
    time_warnings.append(&mut new_time_warnings);
    if time_jumps > time_warnings.len() {
        time_warnings.push(format!(
            "{} time jumps in all (the first {} are listed)",
            time_jumps,
            time_warnings.len()
        ));
    }
    summary.warnings.extend(time_warnings);
    Ok(summary)
}

/// Checks the time t of a sample after `prev` (line `line_no`, 0-based column `col` of `name`) against
/// Ts: time that does not increase is an error (a logger restarted, a file rotated); a step more than
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
    let d = t - prev;
    if d.is_nan() || d <= 0.0 {
        return Err(SysidError::Parse {
            file: name.to_string(),
            line: line_no,
            column: col + 1,
            message: format!(
                "t = {t} after t = {prev}: time went backwards or stood still; expected strictly \
                 increasing time (a restarted logger or a rotated file: start track again on the new record)"
            ),
        });
    }
    Ok(((d - ts).abs() > 0.5 * ts).then(|| {
        format!(
            "{name}:{line_no}: time jumps from {prev} to {t} s (a step of {d} s where Ts = {ts} s): samples \
             missing or the clock jumped; the estimate treats the samples as Ts apart"
        )
    }))
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
        stable: model.is_stable(),
        change,
        pe_rms: tracker.pe_rms(),
        pe_window: tracker.errors.len(),
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
    Ok(TrackSummary {
        samples: tracker.samples(),
        t_end,
        poles: model.as_ref().map(poles).unwrap_or_default(),
        stable: model.as_ref().map(Model::is_stable),
        model,
        pe_rms: tracker.pe_rms(),
        change_points,
        detector_threshold: tracker.detector_threshold(),
        guard_interventions: tracker.guard_interventions(),
        warnings,
    })
}
