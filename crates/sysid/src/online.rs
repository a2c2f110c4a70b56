//! Online tracking (`ipa-sysid track`): the recursive estimator run sample by sample on data as they
//! arrive, with a change detector on its prediction errors.
//!
//! [`Tracker::push`] does, for sample k (counted from 0), exactly what the first pass of
//! [`RecursiveLeastSquares`](crate::RecursiveLeastSquares) (`identify --method rls --passes 1`) does at
//! row k: no regression before k0 = max(na, nk + nb − 1); for a Hammerstein model at k > k0 the
//! deadzone of the switching functions and of x̂ is taken from the latest θ̂ (breakpoints clamped to
//! ±limit, the start deadzone while both slopes are 0), φ(k) is filled by [`Structure::fill_row`] and
//! one RLS update (paper eqs. 9–12) is made by the same estimator type `identify` chooses (plain RLS for
//! `--windup none`, [`RobustRls`](crate::rls_ud::RobustRls) otherwise). The only input `identify` takes from the whole record is
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

use serde::Serialize;
use sysid_core::format::Shortest;

use crate::rls::RecursiveUpdate;
use crate::rls_ud::{recursive_estimator, RlsForm};
use crate::windup::Windup;
use ipa_embedded::cusum::{Cusum, CusumStatus};
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

/// Upper bound on the windows a tracker keeps, samples ([`TrackSettings::pe_window`],
/// [`DetectorSettings::calibration`]): a record's limit, [`sysid_core::data::MAX_SAMPLES`].
pub const MAX_WINDOW: usize = sysid_core::data::MAX_SAMPLES;

/// Samples reserved for a window at the start; it grows with the samples that come, up to its length.
const RESERVE: usize = 4096;

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
        if self.calibration > MAX_WINDOW {
            return Err(SysidError::setting(
                Setting::Other("--detect-calibration"),
                self.calibration,
                &format!("at most {MAX_WINDOW} samples"),
            ));
        }
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
            calibration: Vec::with_capacity(self.calibration.min(RESERVE)),
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
    /// Guard interventions since the last covariance (re)start (out of `updates`).
    guard_hits_since: usize,
    /// The first distinct input levels seen (at most [`LEVELS_KEPT`]), and whether u was ever < 0 or > 0:
    /// what the input excited, for [`Tracker::input_warnings`].
    levels: Vec<f64>,
    negative: bool,
    positive: bool,
    /// The smallest and largest u seen, and the largest u < 0 and the smallest u > 0 (identify's start,
    /// [`DeadzoneStart::from_record`], of the samples so far): what the input reached of the start
    /// breakpoints, and the start to advise when it reached neither (audit s16 L8).
    u_range: [f64; 2],
    max_negative: Option<f64>,
    min_positive: Option<f64>,
    /// Per parameter, whether its regressor was non-zero in an update since the last covariance
    /// (re)start: a parameter never excited (a deadzone branch the input never entered) keeps P = p0
    /// exactly in its direction, whatever the data's units, so the prior's share is judged without it.
    excited: Vec<bool>,
}

/// Distinct input levels a tracker keeps: one more than a two-branch deadzone needs (4).
const LEVELS_KEPT: usize = 5;

/// Share of the updates since the last covariance (re)start in which the deadzone guard acted, above
/// which the estimate is said to be held by the guard (a tracker following its plant leaves the
/// plausible region in a few percent of the updates at most: 1–2 % in audit s31's records that were
/// tracked right, 80 % in the one that was not).
pub const GUARD_SHARE: f64 = 0.2;

impl Tracker {
    /// A tracker; errors name the setting out of range.
    pub fn new(settings: TrackSettings) -> Result<Self, SysidError> {
        let structure = Structure {
            kind: settings.kind,
            orders: settings.orders,
            offset: false,
        };
        structure.check()?;
        if settings.kind == ModelKind::Hammerstein {
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
        if settings.pe_window == 0 || settings.pe_window > MAX_WINDOW {
            return Err(SysidError::setting(
                Setting::Other("--pe-window"),
                settings.pe_window,
                &format!("at least 1 and at most {MAX_WINDOW} samples"),
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
            errors: Vec::with_capacity(settings.pe_window.min(RESERVE)),
            detector,
            changes: Vec::new(),
            guard_hits: 0,
            guard_hits_since: 0,
            levels: Vec::new(),
            negative: false,
            positive: false,
            u_range: [f64::INFINITY, f64::NEG_INFINITY],
            max_negative: None,
            min_positive: None,
            excited: vec![false; n],
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

    /// The restarts of P the estimator made to keep it positive definite (standard form with the
    /// trace bound: `rls_ud::RobustRls::update`), `None` when there were none; [`Tracker::warnings`]
    /// says them in words.
    pub fn covariance_resets(&self) -> Option<crate::rls_ud::CovarianceResets> {
        self.est.covariance_resets()
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
        if self.levels.len() < LEVELS_KEPT && !self.levels.contains(&u) {
            self.levels.push(u);
        }
        self.negative |= u < 0.0;
        self.positive |= u > 0.0;
        self.u_range = [self.u_range[0].min(u), self.u_range[1].max(u)];
        if u < 0.0 {
            self.max_negative = Some(self.max_negative.map_or(u, |m| m.max(u)));
        }
        if u > 0.0 {
            self.min_positive = Some(self.min_positive.map_or(u, |m| m.min(u)));
        }
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
        for (e, r) in self.excited.iter_mut().zip(&self.row) {
            *e |= *r != 0.0;
        }
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
                self.guard_hits_since = 0;
                self.excited.fill(false);
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
        self.guard_hits_since += usize::from(hit);
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

    /// Number of errors in [`Tracker::pe_rms`]: the last [`TrackSettings::pe_window`] or fewer.
    pub fn pe_count(&self) -> usize {
        self.errors.len()
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

    /// Why the change detector could not flag a change at the end of the samples so far, in words
    /// (audit s11 A1): it never armed (fewer than k0 + warm-up + calibration samples, or errors that
    /// were exactly 0, which keep it calibrating), or it was arming again after the last detected
    /// change. `None` when it is armed, or without a detector.
    pub fn detector_unarmed_warning(&self) -> Option<String> {
        let s = self.settings.detector?;
        if self.detector_state().is_some() {
            return None;
        }
        let arming = s.warmup + s.calibration;
        Some(match self.changes.last() {
            None => {
                let needed = self.k0 + arming;
                if self.k >= needed {
                    "the change detector never armed: its calibration errors were all 0 (σ̂² = 0, a \
                     noise-free record), so no change could be detected"
                        .to_string()
                } else {
                    format!(
                        "the change detector never armed (it needs k0 + warm-up + calibration = {} + {} + {} \
                         = {needed} samples, the record has {}): no change could be detected",
                        self.k0, s.warmup, s.calibration, self.k
                    )
                }
            }
            Some(&c) => format!(
                "the change detector was arming again after the change at k = {c} (warm-up + calibration = \
                 {arming} samples; {} came after it): a later change could not be detected",
                self.k - c - 1
            ),
        })
    }

    /// What the input left undetermined in a deadzone estimate (audit s12 F7: `identify` refuses such a
    /// record, a live tracker cannot, so it says so at the end): fewer distinct levels than the deadzone
    /// has free parameters on its excited branches (4 with both, as `identify`'s check), or a branch the
    /// input never reached, whose breakpoint and slope are still the start's. For an ARX tracker, see below.
    /// `model` is the current estimate ([`Tracker::model`]), whose values of an unexcited branch are
    /// named as reported.
    ///
    /// An ARX tracker whose input took one level only (constant, or 0 throughout) says that its input
    /// terms b (and with them the gain and, when y settles, the poles) are not determined: `identify`
    /// refuses such a record as not persistently exciting whatever the windup protection (audit s20
    /// H-1), a tracker cannot refuse, so it says so at the end.
    pub fn input_warnings(&self, model: Option<&Model>) -> Vec<String> {
        if self.k == 0 {
            return Vec::new();
        }
        if self.structure.kind != ModelKind::Hammerstein {
            return match self.levels.as_slice() {
                [level] => vec![format!(
                    "the input took only 1 distinct level ({level}): a constant input does not excite \
                     the model's input terms (identify refuses such a record as not persistently \
                     exciting), so the estimate of b, and of the gain and poles with it, is not \
                     determined by the data"
                )],
                _ => Vec::new(),
            };
        }
        let mut w = Vec::new();
        let need = crate::blocks::deadzone_levels_needed(self.negative && self.positive);
        if self.levels.len() < need {
            let list: Vec<String> = self.levels.iter().map(f64::to_string).collect();
            w.push(format!(
                "the input took only {} distinct level(s) ({}): a deadzone needs at least {need} to be \
                 determined (identify does not estimate it from such a record either: it refuses the \
                 record, or with --offset fixes what the levels cannot determine and says so), so the \
                 deadzone estimate is not determined by the data",
                self.levels.len(),
                list.join(", ")
            ));
        }
        let start = self.settings.start;
        let d = model.and_then(Model::deadzone);
        let [lo, hi] = self.u_range;
        let (left, right) = self.branches_reached();
        if self.negative && self.positive && !left && !right {
            // Both signs, but within the start's deadzone at every sample: x(k) = 0 throughout, so the
            // tracked model never used the input (audit s16 L8: ball and beam, |u| < 0.031 with the
            // PWM start ±1). The start identify would take from these samples is the way out.
            let advice = match (self.max_negative, self.min_positive) {
                (Some(l), Some(r)) => format!(
                    "; start inside the input's range, as identify would from these samples: --b-l0 {} \
                     --b-r0 {} --breakpoint-limit {}",
                    Shortest(l),
                    Shortest(r),
                    Shortest(lo.abs().max(hi.abs()))
                ),
                _ => String::new(),
            };
            w.push(format!(
                "no input sample passed the start breakpoints --b-l0 {} / --b-r0 {} (the input stayed \
                 within [{}, {}]): the deadzone's output x(k) was 0 at every sample, so the input was \
                 never used and the tracked model is y on its own past only{advice}",
                Shortest(start.b_l0),
                Shortest(start.b_r0),
                Shortest(lo),
                Shortest(hi)
            ));
            return w;
        }
        for (excited, reached, side, b0, reported) in [
            (
                self.negative,
                left,
                "negative: the left branch (b_l, m_l)",
                start.b_l0,
                d.map(|d| format!("b_l = {}, m_l = {}", d.b_l, d.m_l)),
            ),
            (
                self.positive,
                right,
                "positive: the right branch (b_r, m_r)",
                start.b_r0,
                d.map(|d| format!("b_r = {}, m_r = {}", d.b_r, d.m_r)),
            ),
        ] {
            if excited && !reached {
                let (flag, extreme) = if b0 < 0.0 {
                    ("--b-l0", lo)
                } else {
                    ("--b-r0", hi)
                };
                let branch = side.split_once(": ").map_or(side, |(_, b)| b);
                w.push(format!(
                    "the input never passed the start breakpoint {flag} {} (its extreme is {}): {branch} \
                     is not estimated from the data: its key terms never left their start; pass {flag} \
                     within the input's range",
                    Shortest(b0),
                    Shortest(extreme)
                ));
            }
            if !excited {
                w.push(format!(
                    "the input was never {side} is not estimated from the data{}: its key terms never \
                     left their start, and its switching function uses the start's breakpoint {b0} \
                     (--b-l0/--b-r0 in the input's units)",
                    reported.map_or(String::new(), |r| format!(" (the estimate reports {r}, no value \
                        of the plant's)"))
                ));
            }
        }
        w
    }

    /// A warning (audit s11 A2) when a change was detected and the estimator was not restarted
    /// ([`TrackSettings::restart_on_change`] off): the final estimate still carries the samples before
    /// the change, so it blends both plants. With forgetting ρ < 1 the old samples fade with a memory
    /// of about 1/(1 − ρ) samples; no warning once 5 memories have passed since the last change.
    pub fn blended_model_warning(&self) -> Option<String> {
        let &c = self.changes.last()?;
        if self.settings.restart_on_change {
            return None;
        }
        let since = self.k - c - 1;
        let rho = self.settings.forgetting;
        let memory = if rho < 1.0 {
            let m = 1.0 / (1.0 - rho);
            if since as f64 > 5.0 * m {
                return None;
            }
            format!(" (forgetting ρ = {rho} remembers about {m:.0} samples; {since} came after it)")
        } else {
            String::new()
        };
        Some(format!(
            "{} change(s) detected (the last at k = {c}) without --restart-on-change: the final model is \
             estimated from the samples before and after the change{memory}, a blend of both plants, not \
             the plant after it; run again with --restart-on-change for that",
            self.changes.len()
        ))
    }

    /// Whether the input passed the start's left and right breakpoints (u < b_l0, u > b_r0): a branch
    /// whose start breakpoint no sample passed has a switching function that stayed 0, so its key terms
    /// were never estimated.
    fn branches_reached(&self) -> (bool, bool) {
        let start = self.settings.start;
        (self.u_range[0] < start.b_l0, self.u_range[1] > start.b_r0)
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
        if let Some(r) = self.covariance_resets() {
            w.push(crate::Warning::CovarianceReset(r).to_string());
        }
        // Without forgetting the recursion is least squares regularised by I / p0: with regressors
        // small against 1/p0 the start holds the estimate (audit s35 H-3). (Under forgetting, P also
        // grows where the recent data do not excite: the other warnings say that.) Judged once the
        // estimate has had its 10 n updates (before, the warning above says it is converging).
        // Over the excited parameters only: one whose regressor was zero at every update (a branch
        // the input never entered, said by `input_warnings`) keeps P = p0 exactly there (audit s37 M-1).
        if self.settings.forgetting == 1.0 && self.updates >= 10 * n {
            let idx: Vec<usize> = (0..self.excited.len())
                .filter(|&i| self.excited[i])
                .collect();
            if !idx.is_empty() {
                let p = self.est.covariance();
                let sub = p.select_rows(&idx).select_columns(&idx);
                let share = sub.singular_values().max() / self.settings.p0;
                if let Some(p) = crate::trust::prior_warning("track", share, self.settings.p0) {
                    w.push(p.to_string());
                }
            }
        }
        // The verdict every command reports (`Model::stability`), in `identify`'s words.
        if let Some(s) = crate::Warning::if_not_settling(model) {
            w.push(format!("the current model: {s}"));
        }
        // The guard keeps the switching functions plausible, not the estimate: when it acts on a large
        // share of the updates, the raw deadzone keeps leaving the plausible region and the one shown
        // is not what these data determine (audit s31 H-1: b_r = 4.03 where 40 was true and batch least
        // squares on the same rows gave 40.1 ± 0.7, guard acting on 4819 of 5989 updates, no warning).
        if self.settings.guard && self.updates >= 10 * n {
            let share = self.guard_hits_since as f64 / self.updates as f64;
            if share > GUARD_SHARE {
                w.push(format!(
                    "the deadzone guard replaced an implausible branch in {} of the {} updates since the \
                     {} ({:.0} %): the raw estimate keeps leaving the plausible region, so the deadzone \
                     shown is held by the guard, not determined by these data (a change of the plant the \
                     detector missed, too little excitation of a branch, or a structure that does not fit; \
                     compare `identify --method ls` on the same rows)",
                    self.guard_hits_since,
                    self.updates,
                    if self.changes.is_empty() || !self.settings.restart_on_change {
                        "start"
                    } else {
                        "last detected change"
                    },
                    100.0 * share
                ));
            }
        }
        if let Some(d) = model.deadzone() {
            // A branch the input never reached is not estimated (its 0s are no verdict on the data;
            // `input_warnings` says so): only the excited branches are judged (audit s14 L-h).
            let (left, right) = self.branches_reached();
            let left_ok = !left || (d.m_l > 0.0 && d.b_l <= 0.0);
            let right_ok = !right || (d.m_r > 0.0 && d.b_r >= 0.0);
            if !(left_ok && right_ok) {
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
