//! The C interface (`include/ipa_embedded.h`, generated from this file by cbindgen): the paper's
//! recursive Hammerstein estimator, the CUSUM change detector, the PI controller and the deadzone
//! compensator, each state in
//! storage the caller provides (no heap), f64 (`double`) throughout.
//!
//! Fixed maximum orders: na ≤ [`IPA_MAX_NA`], nb ≤ [`IPA_MAX_NB`], nk ≤ [`IPA_MAX_NK`] (so at most 19
//! parameters and delay lines of 15 samples). The state of any order takes
//! [`ipa_hrls_state_size`] bytes (≤ [`IPA_HRLS_STATE_BYTES`] on every target), aligned to
//! [`ipa_hrls_state_align`] (8: `double` alignment).
//!
//! Return codes: [`IPA_OK`] (0), [`IPA_PENDING`] (1: sample buffered, no estimate update yet),
//! [`IPA_ALARM`] (2: a change), [`IPA_NOT_PHYSICAL`] (3: a deadzone estimate that is no valve's yet), a
//! non-negative count for the getters, or a negative [`crate::Error`] code: [`IPA_ERR_SETTING`] (−1)
//! … [`IPA_ERR_INDEFINITE`] (−10).
//! No function panics or aborts; every pointer is checked for null and alignment, the storage length
//! against the state size, and a marker word against uninitialised storage.
//!
//! Call sequence: `ipa_hrls_init` once (or `ipa_hrls_record_start` first to take the breakpoints from a
//! whole record, as `ipa-sysid identify` does), then `ipa_hrls_update(u(k), y(k))` every sample,
//! then the getters whenever the model is wanted.

use core::ffi::c_void;
use core::mem::{align_of, size_of};

use crate::cusum::{Cusum, CusumStatus};
use crate::deadzone::{Compensator, Deadzone, SlopeMode};
use crate::hammerstein::{HammersteinRls, HammersteinSettings};
use crate::pi::{AntiWindup, Pi};
use crate::position::{
    BrakeSettings, NudgeSettings, PositionController, PositionSettings, ShortApproachSettings,
};
use crate::rls::Form;
use crate::Error;

/// Largest na (order of A) of the C estimator.
pub const IPA_MAX_NA: u32 = 8;
/// Largest nb (coefficients of B, b1 = 1) of the C estimator.
pub const IPA_MAX_NB: u32 = 8;
/// Largest nk (input delay in samples) of the C estimator.
pub const IPA_MAX_NK: u32 = 8;
/// An upper bound, valid on every target, of [`ipa_hrls_state_size`] in bytes (for static storage;
/// 3480 since the estimator's plausibility range of [`ipa_hrls_set_range`], 3472 before: C code built
/// against the new header only).
pub const IPA_HRLS_STATE_BYTES: usize = 3480;
/// An upper bound, valid on every target, of [`ipa_pi_state_size`] in bytes (80 on a 64-bit host
/// since the plausibility range: the bound is unchanged).
pub const IPA_PI_STATE_BYTES: usize = 80;

/// An upper bound, valid on every target, of [`ipa_ctl_state_size`] in bytes (the tuned controller;
/// 656 since the plausibility range, 640 before: C code built against the new header only).
pub const IPA_CTL_STATE_BYTES: usize = 656;

/// `ipa_hrls_init` form: P itself, updated by the paper's eq. 12 (`identify --rls-form standard`).
pub const IPA_FORM_STANDARD: u32 = 0;
/// `ipa_hrls_init` form: Bierman's UD factors of P (`identify --rls-form ud`), positive semi-definite
/// whatever the rounding.
pub const IPA_FORM_UD: u32 = 1;

/// Success.
pub const IPA_OK: i32 = 0;
/// `ipa_hrls_update`: the sample filled the delay lines; no estimate update yet (k < max(na, nk+nb−1)).
pub const IPA_PENDING: i32 = 1;
/// `ipa_cusum_update`: the detector's statistic is above its threshold (a change).
pub const IPA_ALARM: i32 = 2;
/// `ipa_hrls_deadzone`: the estimate was written but is not one to compensate with (not finite,
/// b_l > 0 or b_r < 0 beyond the compensators' rounding 1e-9 · limit, or a slope m_l, m_r ≤ 0: too few or too poorly exciting samples so far; a
/// breakpoint beyond ±limit; a coefficient of A showing a pole outside |z| = 2, a diverged estimate;
/// with a range, a slope so steep that one sample of the full command would move the position by more
/// than the range: [`ipa_hrls_deadzone_reason`] says which); not an error.
pub const IPA_NOT_PHYSICAL: i32 = 3;
/// An upper bound, valid on every target, of [`ipa_cusum_state_size`] in bytes.
pub const IPA_CUSUM_STATE_BYTES: usize = 80;
/// A setting is out of range (ρ ∉ (0, 1], P(0) ≤ 0, NaN breakpoint, bad gain, ...).
pub const IPA_ERR_SETTING: i32 = -1;
/// Orders beyond the maximum (or nb = 0).
pub const IPA_ERR_CAPACITY: i32 = -2;
/// A non-finite sample; the state is unchanged.
pub const IPA_ERR_NOT_FINITE: i32 = -3;
/// A numerical failure; the state is unchanged. The RLS update ([`ipa_hrls_update`]) would meet a
/// non-finite value (P or θ̂ overflowed; P found indefinite is [`IPA_ERR_INDEFINITE`]): with ρ < 1 and no
/// windup guard (`max_trace` 0) this is covariance windup (P grows by 1/ρ per sample while the input
/// does not excite, e.g. an actuator at rest, until it overflows or loses definiteness), and it then
/// repeats on EVERY later sample, exciting or not, until [`ipa_hrls_restart_covariance`] (or
/// [`ipa_hrls_init`]): give `max_trace` > 0 to prevent it, or restart the covariance on this code (audit
/// s33 M-3). Or a controller step's command would not be finite (a guard of last resort, audit s19 M-1:
/// [`ipa_ctl_step`] when the command u, the integral I or the derivative term D would not be,
/// [`ipa_pi_step`] when u or the integral would not be), `*u` then not written.
pub const IPA_ERR_NUMERICAL: i32 = -4;
/// An output buffer is too short.
pub const IPA_ERR_LENGTH: i32 = -5;
/// A null pointer.
pub const IPA_ERR_NULL: i32 = -6;
/// The storage is too small or misaligned.
pub const IPA_ERR_STORAGE: i32 = -7;
/// The storage does not hold an initialised state.
pub const IPA_ERR_NOT_INITIALISED: i32 = -8;
/// A controller sample with r or y outside the plausibility range set by [`ipa_pi_set_range`] or
/// [`ipa_ctl_set_range`]: a wild sample (an encoder glitch, a unit slip) refused; the state is
/// unchanged and `*u` not written (hold the previous command or go safe). Or an estimator sample
/// ([`ipa_hrls_update`]) with y outside the range of [`ipa_hrls_set_range`] or |u| > limit: not taken,
/// the state unchanged.
pub const IPA_ERR_RANGE: i32 = -9;
/// [`ipa_hrls_update`] with [`IPA_FORM_STANDARD`] (eq. 12) found ρ + φᵀPφ ≤ 0: P has lost its positive
/// definiteness to rounding (an ill-conditioned P: in this f64 interface when P winds up without the
/// guard, `max_trace` 0; in f32 from Rust on IPA records). The state is unchanged but P does not
/// recover: later samples are mostly refused the same way. Start again with [`IPA_FORM_UD`] (never
/// refused so) or with a trace bound `max_trace`.
pub const IPA_ERR_INDEFINITE: i32 = -10;

const MAX_N: usize = 3 + IPA_MAX_NA as usize + IPA_MAX_NB as usize;
const MAX_D: usize = IPA_MAX_NK as usize + IPA_MAX_NB as usize - 1;
const HRLS_MAGIC: u64 = 0x4950_415f_4852_4c53; // "IPA_HRLS"
const PI_MAGIC: u64 = 0x4950_415f_5049_4354; // "IPA_PICT"
const CUSUM_MAGIC: u64 = 0x4950_415f_4355_534d; // "IPA_CUSM"
const CTL_MAGIC: u64 = 0x4950_415f_4354_4c52; // "IPA_CTLR"

#[repr(C)]
struct HrlsState {
    magic: u64,
    est: HammersteinRls<f64, MAX_N, MAX_D>,
}

#[repr(C)]
struct CusumState {
    magic: u64,
    cusum: Cusum<f64>,
}

#[repr(C)]
struct PiState {
    magic: u64,
    pi: Pi<f64>,
}

const _: () = assert!(size_of::<HrlsState>() <= IPA_HRLS_STATE_BYTES);
const _: () = assert!(size_of::<PiState>() <= IPA_PI_STATE_BYTES);
const _: () = assert!(size_of::<CtlState>() <= IPA_CTL_STATE_BYTES);

#[repr(C)]
struct CtlState {
    magic: u64,
    ctl: PositionController<f64>,
}

/// The tuned position controller's settings: the `controller` object of CONTROLLER.json
/// (`ipa-sysid tune --out`), field for field.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IpaController {
    /// Ts: sampling period, s (`ts_s`).
    pub ts: f64,
    /// Kp, counts/mm.
    pub kp: f64,
    /// Ki, counts/(mm·s).
    pub ki: f64,
    /// Kd, counts·s/mm.
    pub kd: f64,
    /// Tf: derivative filter time constant, s (`derivative_filter_s`).
    pub tf: f64,
    /// u_max: command limit, counts.
    pub u_max: f64,
    /// e_h: hold band, mm (`hold_band_mm`).
    pub hold_band: f64,
    /// e_f: fine band, mm (`fine_band_mm`).
    pub fine_band: f64,
    /// 1: restart the integral when the error changes sign (`reset_on_crossing`); 0: not.
    pub reset_on_crossing: i32,
    /// 1: a deadzone inverse with `deadzone` (shift mode, threshold 0, limit u_max); 0: none.
    pub has_deadzone: i32,
    /// The deadzone the compensator inverts (`compensator.deadzone`; a breakpoint on the wrong side of 0
    /// by at most 1e-9 · u_max is taken as 0, as `control` loads the file).
    pub deadzone: IpaDeadzone,
    /// 1: the nudge mode with the `nudge_*` fields (`nudge`); 0: none (the fields are ignored).
    pub has_nudge: i32,
    /// N_r: samples of unchanged y that count as rest (`nudge.rest_samples`).
    pub nudge_rest_samples: u32,
    /// e_n: nudge band, mm (`nudge.band_mm`).
    pub nudge_band: f64,
    /// ρ: ramp rate of a nudge, counts/s (`nudge.ramp_counts_s`).
    pub nudge_ramp: f64,
    /// β: start fraction of the last breakaway command (`nudge.start_fraction`).
    pub nudge_start_fraction: f64,
    /// γ: cut fraction of the starting error (`nudge.cut_fraction`).
    pub nudge_cut_fraction: f64,
    /// e_r: rest band, mm (`nudge.rest_band_mm`; 0 = none, as in a file without it).
    pub nudge_rest_band: f64,
    /// e_c: ramp-and-cut band, mm (`nudge.cut_band_mm`; 0 = off, as in a file without it).
    pub nudge_cut_band: f64,
    /// ρ_min: ramp-and-cut's slowest ramp, counts/s (`nudge.min_ramp_counts_s`; 0 = off, as in a file
    /// without it).
    pub nudge_min_ramp: f64,
    /// e_v: ramp-and-cut's creep limit, mm per sample (`nudge.creep_step_mm`; 0 = off: the nudge
    /// ends at the first count, as in a file without it; issue 25, session 18).
    pub nudge_creep_step: f64,
    /// a_p: the slip brake's command as a fraction of u_max (`nudge.slip_brake_fraction`; 0 = off,
    /// as in a file without it; issue 25, session 19).
    pub nudge_slip_brake: f64,
    /// T_p: the slip brake's longest pulse, samples (`nudge.slip_brake_samples`; 0 = off).
    pub nudge_slip_brake_samples: u32,
    /// 1: the approach with braking with the `brake_*` fields (`brake`); 0: none (the fields are
    /// ignored; a struct zeroed before it existed runs as then).
    pub has_brake: i32,
    /// T_b: samples of braking (`brake.samples`).
    pub brake_samples: u32,
    /// N_b: samples of unchanged y that end the hold after the brake (`brake.rest_samples`).
    pub brake_rest_samples: u32,
    /// e_a: smallest step approached this way, mm (`brake.min_step_mm`).
    pub brake_min_step: f64,
    /// e_s: switch distance, mm (`brake.switch_mm`).
    pub brake_switch: f64,
    /// τ_b: stopping lead per mm/s towards r, s (`brake.lead_s`).
    pub brake_lead: f64,
    /// a_b: braking command as a fraction of u_max (`brake.strength`).
    pub brake_strength: f64,
    /// κ_b: the lead's learning per braked move, in [0, 1] (`brake.learn`; 0 = off, as in a struct
    /// zeroed before it existed).
    pub brake_learn: f64,
    /// τ_max: the largest learnt lead, s (`brake.lead_max_s`; unused when κ_b = 0).
    pub brake_lead_max: f64,
    /// T_r: samples over which the braking command falls to 0 (`brake.release_samples`; 0 = at once,
    /// as in a struct zeroed before it existed).
    pub brake_release: u32,
    /// T_s: samples of the short-step approach's brake (`short_approach.brake_samples`).
    pub short_samples: u32,
    /// N_s: samples of unchanged y that end its hold (`short_approach.rest_samples`).
    pub short_rest_samples: u32,
    /// e_m: largest step driven by the short-step approach, mm (`short_approach.max_step_mm`; 0 =
    /// none, as in a struct zeroed before it existed: the `short_*` fields are then ignored).
    pub short_max_step: f64,
    /// U: its drive as a fraction of u_max (`short_approach.drive_fraction`).
    pub short_drive_fraction: f64,
    /// ρ_a: its guard ramp until the piston first moves, counts/s (`short_approach.ramp_counts_s`).
    pub short_ramp: f64,
    /// e_s': its switch distance, mm (`short_approach.switch_mm`).
    pub short_switch: f64,
    /// τ_s: its stopping lead per mm/s towards r, s (`short_approach.lead_s`).
    pub short_lead: f64,
    /// a_s: its braking command as a fraction of u_max (`short_approach.brake_strength`).
    pub short_strength: f64,
    /// 1: the approach with braking re-brakes a count towards r during its release and hold
    /// (`brake.rebrake`; issue 25, session 19); 0: not (as in a struct zeroed before it existed).
    pub brake_rebrake: i32,
    /// 1: the nudge relearns its breakaway (`nudge.relearn`; issue 25, session 20): at a creeping
    /// nudge's first motion that is already a slip, after N_r samples at rest following a held
    /// nudge's first count (the ramp resumes), and the slip brake lasts while the piston slips;
    /// 0: not (as in a struct zeroed before it existed).
    pub nudge_relearn: i32,
    /// 1: the approach with braking's full command ends at the sample whose next one would pass the
    /// switch, that last sample at the fraction of u_max that reaches it (`brake.preview`; issue 25,
    /// session 20); 0: not (as in a struct zeroed before it existed).
    pub brake_preview: i32,
    /// 1: the same preview for the short-step approach's drive (`short_approach.preview`; session
    /// 20); 0: not.
    pub short_preview: i32,
    /// κ_s: the short-step approach's breakaway seed, in [0, 1] (`short_approach.breakaway_seed`;
    /// issue 25, session 23; 0 = off, as in a struct zeroed before it existed).
    pub short_seed: f64,
    /// v_s: the seed only at a switch speed of at most v_s, mm/s (`short_approach.seed_speed_mm_s`;
    /// 0 = at any speed).
    pub short_seed_speed: f64,
    /// 1: the held nudge learns its cut fraction per side (`nudge.cut_learn`; issue 25, session 23):
    /// doubled after a held nudge that stopped short of half its error, halved back (to γ) after
    /// one that passed r; 0: not (as in a struct zeroed before it existed).
    pub nudge_cut_learn: i32,
}
const _: () = assert!(size_of::<CusumState>() <= IPA_CUSUM_STATE_BYTES);
const _: () = assert!(MAX_D >= IPA_MAX_NA as usize);

/// The deadzone x = f(u) of paper eq. (1): breakpoints in counts, slopes in x per count.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IpaDeadzone {
    /// b_l: left breakpoint (counts).
    pub b_l: f64,
    /// b_r: right breakpoint (counts).
    pub b_r: f64,
    /// m_l: left slope.
    pub m_l: f64,
    /// m_r: right slope.
    pub m_r: f64,
}

fn code(r: Result<i32, Error>) -> i32 {
    match r {
        Ok(v) => v,
        Err(e) => e.code(),
    }
}

/// Checks `mem` (non-null, aligned for T, `len` ≥ size of T).
fn check_storage<T>(mem: *const c_void, len: usize) -> Result<(), Error> {
    if mem.is_null() {
        return Err(Error::Null);
    }
    if len < size_of::<T>() || !(mem as *const T).is_aligned() {
        return Err(Error::Storage);
    }
    Ok(())
}

/// The state in `mem` when it carries the marker `magic` (first word).
///
/// # Safety
/// `mem` must be null or point to at least size_of::<T>() bytes that were written by the matching
/// `*_init` (or hold any other bytes, which the marker then rejects in practice).
unsafe fn state<'a, T>(mem: *const c_void, magic: u64) -> Result<&'a T, Error> {
    check_storage::<T>(mem, size_of::<T>())?;
    // SAFETY: non-null and aligned for T (whose first field is the u64 marker); readable per the contract.
    if unsafe { (mem as *const u64).read() } != magic {
        return Err(Error::NotInitialised);
    }
    // SAFETY: the marker says `*_init` wrote a T here.
    Ok(unsafe { &*(mem as *const T) })
}

/// Mutable variant of [`state`].
///
/// # Safety
/// As [`state`], and no other reference to the state may be live.
unsafe fn state_mut<'a, T>(mem: *mut c_void, magic: u64) -> Result<&'a mut T, Error> {
    // SAFETY: forwarded contract.
    unsafe { state::<T>(mem, magic)? };
    // SAFETY: as in `state`; exclusive per the contract.
    Ok(unsafe { &mut *(mem as *mut T) })
}

/// Writes `value` into checked storage; on failure clears the marker of storage large enough to hold it.
///
/// # Safety
/// `mem` must be null or writable for `len` bytes.
unsafe fn init<T>(mem: *mut c_void, len: usize, value: Result<T, Error>) -> i32 {
    if let Err(e) = check_storage::<T>(mem, len) {
        return e.code();
    }
    match value {
        Ok(v) => {
            // SAFETY: checked non-null, aligned and large enough; writable per the contract.
            unsafe { (mem as *mut T).write(v) };
            IPA_OK
        }
        Err(e) => {
            // SAFETY: as above; the first word of every state is its u64 marker.
            unsafe { (mem as *mut u64).write(0) };
            e.code()
        }
    }
}

/// Size in bytes of the estimator state (for any orders up to the maximum).
#[no_mangle]
pub extern "C" fn ipa_hrls_state_size() -> usize {
    size_of::<HrlsState>()
}

/// Alignment in bytes that the estimator storage needs (that of `double`/`uint64_t`).
#[no_mangle]
pub extern "C" fn ipa_hrls_state_align() -> usize {
    align_of::<HrlsState>()
}

/// The breakpoints `ipa-sysid identify` starts from for a whole record of `n` commands `u` (counts):
/// `*b_l0` = the largest u < 0 (−∞ when none), `*b_r0` = the smallest u > 0 (+∞ when none),
/// `*limit` = max |u|. Returns [`IPA_OK`], [`IPA_ERR_NULL`] or [`IPA_ERR_NOT_FINITE`] when a command
/// is NaN or ±∞ (the outputs are then not written; audit s19 L-1).
///
/// # Safety
/// `u` must point to `n` readable doubles (or be null with n = 0); the outputs must be writable.
#[no_mangle]
pub unsafe extern "C" fn ipa_hrls_record_start(
    u: *const f64,
    n: usize,
    b_l0: *mut f64,
    b_r0: *mut f64,
    limit: *mut f64,
) -> i32 {
    if b_l0.is_null() || b_r0.is_null() || limit.is_null() || (u.is_null() && n > 0) {
        return IPA_ERR_NULL;
    }
    let record: &[f64] = if n == 0 {
        &[]
    } else {
        // SAFETY: non-null, n readable doubles per the contract.
        unsafe { core::slice::from_raw_parts(u, n) }
    };
    if !record.iter().all(|v| v.is_finite()) {
        return IPA_ERR_NOT_FINITE;
    }
    let s = HammersteinSettings::<f64>::paper().from_record(record);
    // SAFETY: non-null and writable per the contract.
    unsafe {
        b_l0.write(s.b_l0);
        b_r0.write(s.b_r0);
        limit.write(s.limit);
    }
    IPA_OK
}

/// Initialises the recursive Hammerstein estimator in `mem` (`len` bytes, ≥ [`ipa_hrls_state_size`],
/// aligned to [`ipa_hrls_state_align`]): orders na ≤ 8, 1 ≤ nb ≤ 8, nk ≤ 8; forgetting ρ ∈ (0, 1];
/// P(0) = p0 · I (p0 > 0, `identify` uses 1e6); initial breakpoints b_l0 ≤ 0 ≤ b_r0 in counts (b_l0 = −∞
/// or b_r0 = +∞ allowed for an unexcited branch; NaN, b_l0 > 0 or b_r0 < 0 give [`IPA_ERR_SETTING`]);
/// `limit` ≥ 0 bounds |b̂| (counts); `max_trace` > 0 bounds tr P (windup guard), 0 for none; `form`
/// [`IPA_FORM_STANDARD`] (the paper's eq. 12) or [`IPA_FORM_UD`].
/// Returns [`IPA_OK`] or a negative code (the storage is then marked uninitialised).
///
/// # Safety
/// `mem` must be null or writable for `len` bytes, and not used by another thread during the call.
#[no_mangle]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn ipa_hrls_init(
    mem: *mut c_void,
    len: usize,
    na: u32,
    nb: u32,
    nk: u32,
    forgetting: f64,
    p0: f64,
    b_l0: f64,
    b_r0: f64,
    limit: f64,
    max_trace: f64,
    form: u32,
) -> i32 {
    let form = match form {
        IPA_FORM_STANDARD => Ok(Form::Standard),
        IPA_FORM_UD => Ok(Form::Ud),
        _ => Err(Error::Setting),
    };
    let est = match form {
        Err(e) => Err(e),
        Ok(_) if na > IPA_MAX_NA || nb > IPA_MAX_NB || nk > IPA_MAX_NK => Err(Error::Capacity),
        Ok(form) => {
            let s = HammersteinSettings {
                na: na as usize,
                nb: nb as usize,
                nk: nk as usize,
                forgetting,
                p0,
                b_l0,
                b_r0,
                limit,
                max_trace: (max_trace != 0.0).then_some(max_trace),
                form,
            };
            HammersteinRls::new(s).map(|est| HrlsState {
                magic: HRLS_MAGIC,
                est,
            })
        }
    };
    // SAFETY: forwarded contract.
    unsafe { init(mem, len, est) }
}

/// Feeds sample k: command u(k) (counts) and position y(k) (mm). Returns [`IPA_OK`] after an estimate
/// update (then `*eps`, when not null, is the a-priori prediction error ε(k) in mm), [`IPA_PENDING`]
/// while the delay lines fill, or a negative code (state unchanged): [`IPA_ERR_NOT_FINITE`] for a
/// NaN/±∞ sample, [`IPA_ERR_RANGE`] with a range ([`ipa_hrls_set_range`]) for y outside it or
/// |u| > limit, [`IPA_ERR_NUMERICAL`] for a non-finite value in the update, [`IPA_ERR_INDEFINITE`]
/// when eq. 12's P has lost its positive definiteness (with ρ < 1 and no `max_trace` either may be
/// covariance windup, repeated on every later sample until [`ipa_hrls_restart_covariance`]).
///
/// # Safety
/// `mem` must be storage passed to a successful [`ipa_hrls_init`] (or null); `eps` null or writable.
#[no_mangle]
pub unsafe extern "C" fn ipa_hrls_update(mem: *mut c_void, u: f64, y: f64, eps: *mut f64) -> i32 {
    // SAFETY: forwarded contract.
    let st = match unsafe { state_mut::<HrlsState>(mem, HRLS_MAGIC) } {
        Ok(st) => st,
        Err(e) => return e.code(),
    };
    code(st.est.update(u, y).map(|e| match e {
        Some(e) => {
            if !eps.is_null() {
                // SAFETY: non-null and writable per the contract.
                unsafe { eps.write(e) };
            }
            IPA_OK
        }
        None => IPA_PENDING,
    }))
}

/// Writes the fitted deadzone (b_r = θ̂₂/θ̂₁, b_l = θ̂₄/θ̂₃, m_r = θ̂₁, m_l = θ̂₃; a non-finite ratio gives
/// 0) to `*out`. Returns [`IPA_OK`], [`IPA_NOT_PHYSICAL`] when the estimate written is not one to
/// compensate with (do not compensate with it yet; [`ipa_hrls_deadzone_reason`] says why: 1 not
/// finite, b_l > 0, b_r < 0 or a slope ≤ 0, a breakpoint within 1e-9 · limit of 0 taken as 0 as
/// `ipa_dz_compensate` / `ipa_ctl_init` take it at u_max = limit (no tolerance for an infinite
/// limit); 2 a breakpoint beyond ±limit; 3 a coefficient
/// |a_i| > C(na, i) 2^i, a pole outside |z| = 2: a diverged estimate; 4 with a range, one sample of
/// the full command would move the position by more than y_max − y_min), or a negative code. The
/// rules: `ipa_embedded::HammersteinRls::plausible_deadzone`.
///
/// # Safety
/// As [`ipa_hrls_update`]; `out` null or writable.
#[no_mangle]
pub unsafe extern "C" fn ipa_hrls_deadzone(mem: *const c_void, out: *mut IpaDeadzone) -> i32 {
    // SAFETY: forwarded contract.
    let st = match unsafe { state::<HrlsState>(mem, HRLS_MAGIC) } {
        Ok(st) => st,
        Err(e) => return e.code(),
    };
    if out.is_null() {
        return IPA_ERR_NULL;
    }
    let d = st.est.deadzone();
    // SAFETY: non-null and writable per the contract.
    unsafe {
        out.write(IpaDeadzone {
            b_l: d.b_l,
            b_r: d.b_r,
            m_l: d.m_l,
            m_r: d.m_r,
        })
    };
    match st.est.plausible_deadzone() {
        Ok(_) => IPA_OK,
        Err(_) => IPA_NOT_PHYSICAL,
    }
}

/// Why [`ipa_hrls_deadzone`] returns [`IPA_NOT_PHYSICAL`]: 0 when it returns [`IPA_OK`], else 1 no
/// valve deadzone (not finite, b_l > 0, b_r < 0 beyond 1e-9 · limit, or a slope ≤ 0), 2 a breakpoint beyond ±limit,
/// 3 a coefficient |a_i| > C(na, i) 2^i (a pole outside |z| = 2: a diverged estimate), 4 with a range
/// ([`ipa_hrls_set_range`]), one sample of the full command ±limit would move the modelled position by
/// more than y_max − y_min; or a negative code (storage).
///
/// # Safety
/// As [`ipa_hrls_update`].
#[no_mangle]
pub unsafe extern "C" fn ipa_hrls_deadzone_reason(mem: *const c_void) -> i32 {
    // SAFETY: forwarded contract.
    match unsafe { state::<HrlsState>(mem, HRLS_MAGIC) } {
        Ok(st) => match st.est.plausible_deadzone() {
            Ok(_) => 0,
            Err(why) => why as i32,
        },
        Err(e) => e.code(),
    }
}

/// Sets the estimator's plausibility range [y_min, y_max] (mm) for the position, after
/// [`ipa_hrls_init`] (θ̂, P and the delay lines are kept): from then on [`ipa_hrls_update`] refuses a
/// sample with y outside it, or with a command |u| > limit (the `limit` of [`ipa_hrls_init`]), with
/// [`IPA_ERR_RANGE`], the state unchanged; and [`ipa_hrls_deadzone`] bounds the slopes by it. Without
/// it every finite sample is taken: one garbage position (1000 mm on a 200 mm stroke, or 2e306 from a
/// bad read) corrupts the estimate for good (audit s33 H-2). Typically the stroke with a margin for the
/// sensor's noise, the range of [`ipa_pi_set_range`] / [`ipa_ctl_set_range`].
/// Returns [`IPA_OK`] or a negative code: [`IPA_ERR_SETTING`] for y_min or y_max not finite or
/// y_min ≥ y_max (the range is then unchanged), or a storage code.
///
/// # Safety
/// `mem` storage of a successful [`ipa_hrls_init`] (or null).
#[no_mangle]
pub unsafe extern "C" fn ipa_hrls_set_range(mem: *mut c_void, y_min: f64, y_max: f64) -> i32 {
    // SAFETY: forwarded contract.
    let st = match unsafe { state_mut::<HrlsState>(mem, HRLS_MAGIC) } {
        Ok(st) => st,
        Err(e) => return e.code(),
    };
    match st.est.with_range(y_min, y_max) {
        Ok(est) => {
            st.est = est;
            IPA_OK
        }
        Err(e) => e.code(),
    }
}

/// Which coefficient vector a getter copies.
#[derive(Clone, Copy)]
enum Coefs {
    A,
    B,
    Theta,
}

/// # Safety
/// As [`ipa_hrls_update`]; `out` null or writable for `len` doubles.
unsafe fn coefs(mem: *const c_void, out: *mut f64, len: usize, which: Coefs) -> i32 {
    // SAFETY: forwarded contract.
    let st = match unsafe { state::<HrlsState>(mem, HRLS_MAGIC) } {
        Ok(st) => st,
        Err(e) => return e.code(),
    };
    if out.is_null() {
        return IPA_ERR_NULL;
    }
    // SAFETY: non-null, `len` writable doubles per the contract.
    let out = unsafe { core::slice::from_raw_parts_mut(out, len) };
    let r = match which {
        Coefs::A => st.est.a(out),
        Coefs::B => st.est.b(out),
        Coefs::Theta => {
            let n = st.est.rls().n_params();
            out.get_mut(..n).ok_or(Error::Length).map(|o| {
                o.iter_mut().zip(st.est.theta()).for_each(|(o, t)| *o = *t);
                n
            })
        }
    };
    code(r.map(|n| n as i32))
}

/// Writes a_1..a_na (A = 1 + a_1 q⁻¹ + … + a_na q^−na) to `out` (room for `len` doubles). Returns na
/// (≥ 0) or a negative code ([`IPA_ERR_LENGTH`] when len < na).
///
/// # Safety
/// As [`ipa_hrls_update`]; `out` null or writable for `len` doubles.
#[no_mangle]
pub unsafe extern "C" fn ipa_hrls_a(mem: *const c_void, out: *mut f64, len: usize) -> i32 {
    // SAFETY: forwarded contract.
    unsafe { coefs(mem, out, len, Coefs::A) }
}

/// Writes b_1..b_nb (b_1 = 1) to `out`. Returns nb or a negative code.
///
/// # Safety
/// As [`ipa_hrls_a`].
#[no_mangle]
pub unsafe extern "C" fn ipa_hrls_b(mem: *const c_void, out: *mut f64, len: usize) -> i32 {
    // SAFETY: forwarded contract.
    unsafe { coefs(mem, out, len, Coefs::B) }
}

/// Writes θ̂ = [m_r, m_r b_r, m_l, m_l b_l, a_1..a_na, b_2..b_nb] to `out`. Returns n = 3 + na + nb or a
/// negative code.
///
/// # Safety
/// As [`ipa_hrls_a`].
#[no_mangle]
pub unsafe extern "C" fn ipa_hrls_theta(mem: *const c_void, out: *mut f64, len: usize) -> i32 {
    // SAFETY: forwarded contract.
    unsafe { coefs(mem, out, len, Coefs::Theta) }
}

/// Restarts the covariance P = p0 · I of the estimator in `mem`, keeping θ̂ and the delay lines (what
/// `ipa-sysid track` does after a change alarm; [`ipa_hrls_init`] would restart θ̂ too). Returns
/// [`IPA_OK`] or a negative code.
///
/// # Safety
/// As [`ipa_hrls_update`].
#[no_mangle]
pub unsafe extern "C" fn ipa_hrls_restart_covariance(mem: *mut c_void) -> i32 {
    // SAFETY: forwarded contract.
    match unsafe { state_mut::<HrlsState>(mem, HRLS_MAGIC) } {
        Ok(st) => {
            st.est.restart_covariance();
            IPA_OK
        }
        Err(e) => e.code(),
    }
}

/// Size in bytes of the change detector state.
#[no_mangle]
pub extern "C" fn ipa_cusum_state_size() -> usize {
    size_of::<CusumState>()
}

/// Initialises Page's CUSUM change detector (module `cusum`) in `mem`: the first `warmup` errors are
/// ignored, σ̂² is the mean of ε² over the next `calibration` (≥ 1) errors, then g(k) = max(0, g(k−1) +
/// ε²/σ̂² − `drift`) raises an alarm when g > `threshold` (drift > 1, threshold > 0; 3 and 30 in the
/// firmware, 3 and 60 in `ipa-sysid track`). Returns [`IPA_OK`] or a negative code.
///
/// # Safety
/// `mem` null or writable for `len` bytes, aligned to 8.
#[no_mangle]
pub unsafe extern "C" fn ipa_cusum_init(
    mem: *mut c_void,
    len: usize,
    warmup: u32,
    calibration: u32,
    drift: f64,
    threshold: f64,
) -> i32 {
    let d = Cusum::new(warmup as usize, calibration as usize, drift, threshold).map(|cusum| {
        CusumState {
            magic: CUSUM_MAGIC,
            cusum,
        }
    });
    // SAFETY: forwarded contract.
    unsafe { init(mem, len, d) }
}

/// Feeds the prediction error ε(k) (mm, e.g. `*eps` of [`ipa_hrls_update`]). Returns [`IPA_PENDING`]
/// while warming up or calibrating, [`IPA_OK`] while monitoring without alarm, [`IPA_ALARM`] once g > h
/// (latched until [`ipa_cusum_rearm`]), or a negative code (state unchanged); `*g`, when not null,
/// receives the statistic g(k).
///
/// # Safety
/// `mem` storage of a successful [`ipa_cusum_init`] (or null); `g` null or writable.
#[no_mangle]
pub unsafe extern "C" fn ipa_cusum_update(mem: *mut c_void, eps: f64, g: *mut f64) -> i32 {
    // SAFETY: forwarded contract.
    let st = match unsafe { state_mut::<CusumState>(mem, CUSUM_MAGIC) } {
        Ok(st) => st,
        Err(e) => return e.code(),
    };
    code(st.cusum.update(eps).map(|status| {
        if !g.is_null() {
            // SAFETY: non-null and writable per the contract.
            unsafe { g.write(st.cusum.statistic()) };
        }
        match status {
            CusumStatus::WarmUp | CusumStatus::Calibrating => IPA_PENDING,
            CusumStatus::Monitoring(_) => IPA_OK,
            CusumStatus::Alarm(_) => IPA_ALARM,
        }
    }))
}

/// Clears an alarm (g = 0), keeping σ̂² (e.g. after `ipa_hrls_init` restarted the estimator on the new
/// valve). Returns [`IPA_OK`] or a negative code.
///
/// # Safety
/// `mem` storage of a successful [`ipa_cusum_init`] (or null).
#[no_mangle]
pub unsafe extern "C" fn ipa_cusum_rearm(mem: *mut c_void) -> i32 {
    // SAFETY: forwarded contract.
    match unsafe { state_mut::<CusumState>(mem, CUSUM_MAGIC) } {
        Ok(st) => {
            st.cusum.rearm();
            IPA_OK
        }
        Err(e) => e.code(),
    }
}

/// Size in bytes of the PI controller state.
#[no_mangle]
pub extern "C" fn ipa_pi_state_size() -> usize {
    size_of::<PiState>()
}

/// Initialises a PI controller in `mem`: Kp (counts/mm), Ki (counts/(mm·s)), Ts (s), u_max (counts,
/// 255 for the IPA), `anti_windup` 0 = none, 1 = clamping, 2 = back-calculation with tracking time
/// `tt_s` (s; ignored otherwise). Returns [`IPA_OK`] or a negative code: [`IPA_ERR_SETTING`] among
/// others for Ts outside 1e-6 to 1e4 s, |Kp| or |Ki| above 1e6 or u_max above 1e6 counts (the tuned
/// controller's ranges, [`ipa_ctl_init`]; a subnormal Ts and Ts = 1e300 s were taken, audit s28 L-4).
///
/// # Safety
/// `mem` null or writable for `len` bytes, aligned to 8.
#[no_mangle]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn ipa_pi_init(
    mem: *mut c_void,
    len: usize,
    kp: f64,
    ki: f64,
    ts: f64,
    u_max: f64,
    anti_windup: i32,
    tt_s: f64,
) -> i32 {
    let aw = match anti_windup {
        0 => Ok(AntiWindup::None),
        1 => Ok(AntiWindup::Clamping),
        2 => Ok(AntiWindup::BackCalculation { tt_s }),
        _ => Err(Error::Setting),
    };
    let pi = aw
        .and_then(|aw| Pi::new(kp, ki, ts, u_max, aw))
        .map(|pi| PiState {
            magic: PI_MAGIC,
            pi,
        });
    // SAFETY: forwarded contract.
    unsafe { init(mem, len, pi) }
}

/// One PI sample: set-point r and position y in mm; writes the saturated command (counts) to `*u`.
/// Returns [`IPA_OK`] or a negative code: [`IPA_ERR_NOT_FINITE`] for a non-finite r or y,
/// [`IPA_ERR_RANGE`] for r or y outside the range of [`ipa_pi_set_range`] (when one is set),
/// [`IPA_ERR_NUMERICAL`] when the command or the integral would not be finite (e.g. r − y overflowing);
/// `*u` is then not written and the state is unchanged.
///
/// # Safety
/// `mem` storage of a successful [`ipa_pi_init`] (or null); `u` null or writable.
#[no_mangle]
pub unsafe extern "C" fn ipa_pi_step(mem: *mut c_void, r: f64, y: f64, u: *mut f64) -> i32 {
    // SAFETY: forwarded contract.
    let st = match unsafe { state_mut::<PiState>(mem, PI_MAGIC) } {
        Ok(st) => st,
        Err(e) => return e.code(),
    };
    if u.is_null() {
        return IPA_ERR_NULL;
    }
    code(st.pi.step(r, y).map(|v| {
        // SAFETY: non-null and writable per the contract.
        unsafe { u.write(v) };
        IPA_OK
    }))
}

/// Sets the PI controller's plausibility range [y_min, y_max] (mm) for r and y, after [`ipa_pi_init`]:
/// from then on [`ipa_pi_step`] refuses a sample with r or y outside it with [`IPA_ERR_RANGE`], the
/// state unchanged. Without it one finite wild sample (y = −1e6 mm from an encoder glitch) winds the
/// back-calculation integral for minutes to hours (audit s31 M-6: 54.6 s of reverse command at
/// Kp = 14, Ki = 1, Tt = 14 s, Ts = 0.01 s; the decay time: `ipa_embedded::Pi` and docs/embedded.md).
/// Typically the stroke with a margin for the sensor's noise.
/// Returns [`IPA_OK`] or a negative code: [`IPA_ERR_SETTING`] for y_min or y_max not finite or
/// y_min ≥ y_max (the range is then unchanged), or a storage code.
///
/// # Safety
/// `mem` storage of a successful [`ipa_pi_init`] (or null).
#[no_mangle]
pub unsafe extern "C" fn ipa_pi_set_range(mem: *mut c_void, y_min: f64, y_max: f64) -> i32 {
    // SAFETY: forwarded contract.
    let st = match unsafe { state_mut::<PiState>(mem, PI_MAGIC) } {
        Ok(st) => st,
        Err(e) => return e.code(),
    };
    match st.pi.with_range(y_min, y_max) {
        Ok(pi) => {
            st.pi = pi;
            IPA_OK
        }
        Err(e) => e.code(),
    }
}

/// Size in bytes of the tuned position controller's state.
#[no_mangle]
pub extern "C" fn ipa_ctl_state_size() -> usize {
    size_of::<CtlState>()
}

/// Initialises the tuned position controller (CONTROLLER.json) in `mem` from `settings`, at rest.
/// Returns [`IPA_OK`] or a negative code (a setting out of range, bad storage): [`IPA_ERR_SETTING`]
/// among others for Ts outside 1e-6 to 1e4 s (`ipa_embedded::position::MIN_TS_S` and
/// `ipa_embedded::MAX_TS_S`, the range `control` applies to controller files too; a subnormal Ts gave
/// NaN commands, audit s19 M-1, and Ts = 1e308 s an overflowing integral, audit s21 L-B1), and for
/// Kp, Ki, Kd above 1e6, Tf above 1e4 s, a hold or fine band above 1e4 mm or u_max above 1e6 counts
/// (`ipa_embedded::position::MAX_GAIN` etc., the ranges of a controller file, audit s28 L-4).
///
/// # Safety
/// `mem` null or writable for `len` bytes, aligned to 8; `settings` null or readable.
#[no_mangle]
pub unsafe extern "C" fn ipa_ctl_init(
    mem: *mut c_void,
    len: usize,
    settings: *const IpaController,
) -> i32 {
    if settings.is_null() {
        return IPA_ERR_NULL;
    }
    // SAFETY: non-null and readable per the contract.
    let c = unsafe { settings.read() };
    // The upper end of the range (the floor is also `PositionController::new`'s).
    if !crate::ts_in_range(c.ts) {
        return IPA_ERR_SETTING;
    }
    let compensator = match c.has_deadzone {
        0 => Ok(None),
        1 => {
            let d = Deadzone {
                b_l: c.deadzone.b_l,
                b_r: c.deadzone.b_r,
                m_l: c.deadzone.m_l,
                m_r: c.deadzone.m_r,
            };
            Compensator::new(d, SlopeMode::Shift, 0.0, c.u_max).map(Some)
        }
        _ => Err(Error::Setting),
    };
    let reset_on_crossing = match c.reset_on_crossing {
        0 => Ok(false),
        1 => Ok(true),
        _ => Err(Error::Setting),
    };
    let nudge = match (c.has_nudge, c.nudge_relearn, c.nudge_cut_learn) {
        (0, _, _) => Ok(None),
        (1, relearn @ (0 | 1), cut_learn @ (0 | 1)) => Ok(Some(NudgeSettings {
            band: c.nudge_band,
            ramp: c.nudge_ramp,
            start_fraction: c.nudge_start_fraction,
            rest_samples: c.nudge_rest_samples,
            cut_fraction: c.nudge_cut_fraction,
            rest_band: c.nudge_rest_band,
            cut_band: c.nudge_cut_band,
            min_ramp: c.nudge_min_ramp,
            creep_step: c.nudge_creep_step,
            slip_brake: c.nudge_slip_brake,
            slip_brake_samples: c.nudge_slip_brake_samples,
            relearn: relearn == 1,
            cut_learn: cut_learn == 1,
        })),
        _ => Err(Error::Setting),
    };
    let brake = match (c.has_brake, c.brake_rebrake, c.brake_preview) {
        (0, _, _) => Ok(None),
        (1, rebrake @ (0 | 1), preview @ (0 | 1)) => Ok(Some(BrakeSettings {
            min_step: c.brake_min_step,
            switch: c.brake_switch,
            lead: c.brake_lead,
            strength: c.brake_strength,
            samples: c.brake_samples,
            rest_samples: c.brake_rest_samples,
            learn: c.brake_learn,
            lead_max: c.brake_lead_max,
            release: c.brake_release,
            rebrake: rebrake == 1,
            preview: preview == 1,
        })),
        _ => Err(Error::Setting),
    };
    let short = if c.short_max_step == 0.0 {
        Ok(None)
    } else if !matches!(c.short_preview, 0 | 1) {
        Err(Error::Setting)
    } else {
        Ok(Some(ShortApproachSettings {
            max_step: c.short_max_step,
            drive_fraction: c.short_drive_fraction,
            ramp: c.short_ramp,
            switch: c.short_switch,
            lead: c.short_lead,
            strength: c.short_strength,
            samples: c.short_samples,
            rest_samples: c.short_rest_samples,
            preview: c.short_preview == 1,
            seed: c.short_seed,
            seed_speed: c.short_seed_speed,
        }))
    };
    let state = compensator.and_then(|comp| {
        let s = PositionSettings {
            ts: c.ts,
            kp: c.kp,
            ki: c.ki,
            kd: c.kd,
            tf: c.tf,
            u_max: c.u_max,
            hold_band: c.hold_band,
            fine_band: c.fine_band,
            reset_on_crossing: reset_on_crossing?,
            nudge: nudge?,
            brake: brake?,
            short: short?,
        };
        PositionController::new(s, comp).map(|ctl| CtlState {
            magic: CTL_MAGIC,
            ctl,
        })
    });
    // SAFETY: forwarded contract.
    unsafe { init(mem, len, state) }
}

/// One sample of the tuned controller: set-point r and position y in mm; writes the command (counts)
/// to `*u`. Returns [`IPA_OK`] or a negative code: [`IPA_ERR_NOT_FINITE`] for a non-finite r or y,
/// [`IPA_ERR_RANGE`] for r or y outside the range of [`ipa_ctl_set_range`] (when one is set),
/// [`IPA_ERR_NUMERICAL`] for a finite r or y beyond the controller's reach (64 |v| max(1, Kp, Ki Ts,
/// (1 + Kd)/Ts) not finite: about 1e304 mm at Ts = 0.01 s; a garbage sensor read of 2e306 mm was taken
/// and then wedged every later step, audit s28 M-1) and when the command (or the integral or
/// derivative term) would not be finite (finite but extreme inputs, e.g. a jump of y by 1e300 mm);
/// `*u` is then not written and the state is unchanged (the next sample runs as if this one had not
/// been given).
///
/// # Safety
/// `mem` storage of a successful [`ipa_ctl_init`] (or null); `u` null or writable.
#[no_mangle]
pub unsafe extern "C" fn ipa_ctl_step(mem: *mut c_void, r: f64, y: f64, u: *mut f64) -> i32 {
    // SAFETY: forwarded contract.
    let st = match unsafe { state_mut::<CtlState>(mem, CTL_MAGIC) } {
        Ok(st) => st,
        Err(e) => return e.code(),
    };
    if u.is_null() {
        return IPA_ERR_NULL;
    }
    code(st.ctl.step(r, y).map(|v| {
        // SAFETY: non-null and writable per the contract.
        unsafe { u.write(v) };
        IPA_OK
    }))
}

/// Sets the tuned controller's plausibility range [y_min, y_max] (mm) for r and y, after
/// [`ipa_ctl_init`]: from then on [`ipa_ctl_step`] refuses a sample with r or y outside it with
/// [`IPA_ERR_RANGE`], the state unchanged. Without it a finite wild sample (y = −1e6 mm from an
/// encoder glitch, G = 1e6) is taken, and the filtered derivative carries it as a reverse command
/// for about ln(Kd Ts G/((Tf + Ts)² |u_PI|)) / ln(1 + Ts/Tf) samples, u_PI the PI part's command
/// (`ipa_embedded::PositionController::with_range`). Typically the stroke with a margin for the
/// sensor's noise. Returns [`IPA_OK`] or a negative code: [`IPA_ERR_SETTING`] for y_min or y_max
/// not finite or y_min ≥ y_max (the range is then unchanged), or a storage code.
///
/// # Safety
/// `mem` storage of a successful [`ipa_ctl_init`] (or null).
#[no_mangle]
pub unsafe extern "C" fn ipa_ctl_set_range(mem: *mut c_void, y_min: f64, y_max: f64) -> i32 {
    // SAFETY: forwarded contract.
    let st = match unsafe { state_mut::<CtlState>(mem, CTL_MAGIC) } {
        Ok(st) => st,
        Err(e) => return e.code(),
    };
    match st.ctl.with_range(y_min, y_max) {
        Ok(ctl) => {
            st.ctl = ctl;
            IPA_OK
        }
        Err(e) => e.code(),
    }
}

/// Puts the tuned controller back at rest (integral, derivative and memories to 0).
/// Returns [`IPA_OK`] or a negative code.
///
/// # Safety
/// `mem` storage of a successful [`ipa_ctl_init`] (or null).
#[no_mangle]
pub unsafe extern "C" fn ipa_ctl_reset(mem: *mut c_void) -> i32 {
    // SAFETY: forwarded contract.
    match unsafe { state_mut::<CtlState>(mem, CTL_MAGIC) } {
        Ok(st) => {
            st.ctl.reset();
            IPA_OK
        }
        Err(e) => e.code(),
    }
}

/// Deadzone-inverse compensation of a controller output `u` (counts): `*u_c` = f⁻¹(m_ref u) clamped to
/// ±u_max, 0 when |u| ≤ threshold; `mode` 0 = shift (m_ref = m_r or m_l), 1 = equalise (mean slope).
/// Returns [`IPA_OK`] or a negative code: [`IPA_ERR_SETTING`] (deadzone not finite, b_l > 0 or b_r < 0
/// beyond 1e-9 · u_max (within it an estimate's rounding, taken as 0, as `control` takes it), a slope ≤ 0,
/// ...), then [`IPA_ERR_NOT_FINITE`] for a NaN or ±∞ `u` (audit s19 L-1; `*u_c` is then not written).
///
/// # Safety
/// `dz` null or readable; `u_c` null or writable.
#[no_mangle]
pub unsafe extern "C" fn ipa_dz_compensate(
    dz: *const IpaDeadzone,
    mode: i32,
    threshold: f64,
    u_max: f64,
    u: f64,
    u_c: *mut f64,
) -> i32 {
    if dz.is_null() || u_c.is_null() {
        return IPA_ERR_NULL;
    }
    // SAFETY: non-null and readable per the contract.
    let d = unsafe { dz.read() };
    let mode = match mode {
        0 => SlopeMode::Shift,
        1 => SlopeMode::Equalise,
        _ => return IPA_ERR_SETTING,
    };
    let dz = Deadzone {
        b_l: d.b_l,
        b_r: d.b_r,
        m_l: d.m_l,
        m_r: d.m_r,
    };
    let c = match Compensator::new(dz, mode, threshold, u_max) {
        Ok(c) => c,
        Err(e) => return e.code(),
    };
    if !u.is_finite() {
        return IPA_ERR_NOT_FINITE;
    }
    // SAFETY: non-null and writable per the contract.
    unsafe { u_c.write(c.apply(u)) };
    IPA_OK
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    // Warm-up 1, calibration 2 with ε = ±2 → σ̂² = 4, ν = 3, h = 10: ε = 6 adds 36/4 − 3 = 6 (g = 6),
    // again 6 more (g = 12 > 10: alarm, latched); rearm clears g. Bad settings and storage are refused.
    #[test]
    fn the_c_detector_calibrates_accumulates_and_latches_its_alarm() {
        let mut mem = [0u64; IPA_CUSUM_STATE_BYTES / 8];
        let p = mem.as_mut_ptr() as *mut c_void;
        let mut g = f64::NAN;
        unsafe {
            assert_eq!(ipa_cusum_update(p, 1.0, &mut g), IPA_ERR_NOT_INITIALISED);
            assert_eq!(ipa_cusum_init(p, 8, 1, 2, 3.0, 10.0), IPA_ERR_STORAGE);
            assert_eq!(
                ipa_cusum_init(p, IPA_CUSUM_STATE_BYTES, 1, 2, 1.0, 10.0),
                IPA_ERR_SETTING
            );
            assert_eq!(
                ipa_cusum_init(p, IPA_CUSUM_STATE_BYTES, 1, 2, 3.0, 10.0),
                IPA_OK
            );
            assert_eq!(ipa_cusum_update(p, 100.0, &mut g), IPA_PENDING);
            assert_eq!(ipa_cusum_update(p, 2.0, &mut g), IPA_PENDING);
            assert_eq!(ipa_cusum_update(p, -2.0, &mut g), IPA_PENDING);
            assert_eq!(ipa_cusum_update(p, 6.0, &mut g), IPA_OK);
            assert_eq!(g, 6.0);
            assert_eq!(ipa_cusum_update(p, 6.0, core::ptr::null_mut()), IPA_ALARM);
            assert_eq!(ipa_cusum_update(p, 0.0, &mut g), IPA_ALARM);
            assert_eq!(g, 12.0);
            assert_eq!(ipa_cusum_update(p, f64::NAN, &mut g), IPA_ERR_NOT_FINITE);
            assert_eq!(ipa_cusum_rearm(p), IPA_OK);
            assert_eq!(ipa_cusum_update(p, 0.0, &mut g), IPA_OK);
            assert_eq!(g, 0.0);
            assert_eq!(ipa_cusum_rearm(core::ptr::null_mut()), IPA_ERR_NULL);
            assert_eq!(
                ipa_hrls_restart_covariance(core::ptr::null_mut()),
                IPA_ERR_NULL
            );
            // Detector storage is not estimator storage.
            assert_eq!(ipa_hrls_restart_covariance(p), IPA_ERR_NOT_INITIALISED);
        }
        assert!(ipa_cusum_state_size() <= IPA_CUSUM_STATE_BYTES);
    }

    // Audit s28 L-8: a deadzone estimate that is no valve's is written but flagged IPA_NOT_PHYSICAL.
    // Plant: x = f(u) with b_l = −40, b_r = 50, m_l = 0.8, m_r = 1.2 counts → mm/s scale, then
    // y(k) = 1.2 y(k−1) − 0.35 y(k−2) + x(k−1) (na = 2, nb = 1, nk = 1: b₀ = 1, as the estimator's).
    #[test]
    fn a_deadzone_estimate_that_is_no_valves_is_flagged() {
        let truth = Deadzone {
            b_l: -40.0,
            b_r: 50.0,
            m_l: 0.8,
            m_r: 1.2,
        };
        // A command that switches every 7 samples among levels on both sides (a fixed LCG, no crate).
        let mut seed = 12345u64;
        let mut level = 0.0;
        let command = |k: usize, only_right: bool, seed: &mut u64, level: &mut f64| {
            if k % 7 == 0 {
                *seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let r = (*seed >> 11) as f64 / (1u64 << 53) as f64; // [0, 1)
                *level = if only_right {
                    255.0 * r
                } else {
                    510.0 * r - 255.0
                };
            }
            *level
        };
        let run = |samples: usize, only_right: bool, seed: &mut u64, level: &mut f64| {
            let mut mem = [0u64; IPA_HRLS_STATE_BYTES / 8];
            let p = mem.as_mut_ptr() as *mut c_void;
            let (mut y1, mut y2, mut x1) = (0.0, 0.0, 0.0);
            let mut out = IpaDeadzone {
                b_l: f64::NAN,
                b_r: f64::NAN,
                m_l: f64::NAN,
                m_r: f64::NAN,
            };
            unsafe {
                let init = ipa_hrls_init(
                    p,
                    IPA_HRLS_STATE_BYTES,
                    2,
                    1,
                    1,
                    1.0,
                    1e6,
                    -1.0,
                    1.0,
                    255.0,
                    0.0,
                    IPA_FORM_STANDARD,
                );
                assert_eq!(init, IPA_OK);
                for k in 0..samples {
                    let u = command(k, only_right, seed, level);
                    let y = 1.2 * y1 - 0.35 * y2 + x1;
                    let rc = ipa_hrls_update(p, u, y, core::ptr::null_mut());
                    assert!(rc >= 0, "update {k}: {rc}");
                    (y2, y1, x1) = (y1, y, truth.apply(u));
                }
                let rc = ipa_hrls_deadzone(p, &mut out);
                (rc, out)
            }
        };
        // Both valves exercised for 3000 samples: the estimate is the valve's (signs and slopes).
        let (rc, d) = run(3000, false, &mut seed, &mut level);
        assert_eq!(rc, IPA_OK, "{d:?}");
        assert!(
            d.b_l <= 0.0 && d.b_r >= 0.0 && d.m_l > 0.0 && d.m_r > 0.0,
            "{d:?}"
        );
        // Only the right valve ever opened: the left branch's parameters never move from θ̂(0) = 0,
        // so m_l = 0 exactly: written, and flagged.
        let (rc, d) = run(3000, true, &mut seed, &mut level);
        assert_eq!(rc, IPA_NOT_PHYSICAL, "{d:?}");
        assert_eq!(d.m_l, 0.0, "{d:?}");
        assert!(d.m_r > 0.0, "the estimate is written: {d:?}");
    }

    // The storage is checked: null, too short, misaligned, uninitialised; a failed init marks it so.
    #[test]
    fn storage_is_checked_before_use() {
        let mut mem = [0u64; IPA_HRLS_STATE_BYTES / 8];
        let p = mem.as_mut_ptr() as *mut c_void;
        let len = IPA_HRLS_STATE_BYTES;
        unsafe {
            assert_eq!(
                ipa_hrls_update(core::ptr::null_mut(), 0.0, 0.0, core::ptr::null_mut()),
                IPA_ERR_NULL
            );
            assert_eq!(
                ipa_hrls_update(p, 0.0, 0.0, core::ptr::null_mut()),
                IPA_ERR_NOT_INITIALISED
            );
            let ok = |na, nb, nk, rho| {
                ipa_hrls_init(p, len, na, nb, nk, rho, 1e6, -1.0, 1.0, 255.0, 0.0, 0)
            };
            assert_eq!(
                ipa_hrls_init(p, 16, 3, 1, 1, 1.0, 1e6, -1.0, 1.0, 255.0, 0.0, 0),
                IPA_ERR_STORAGE
            );
            let odd = (p as *mut u8).add(4) as *mut c_void;
            assert_eq!(
                ipa_hrls_init(odd, len - 8, 3, 1, 1, 1.0, 1e6, -1.0, 1.0, 255.0, 0.0, 0),
                IPA_ERR_STORAGE
            );
            assert_eq!(ok(8, 8, 8, 0.99), IPA_OK, "the maximum orders fit");
            assert_eq!(ok(9, 1, 1, 1.0), IPA_ERR_CAPACITY);
            assert_eq!(
                ipa_hrls_update(p, 0.0, 0.0, core::ptr::null_mut()),
                IPA_ERR_NOT_INITIALISED
            );
            assert_eq!(ok(3, 1, 1, 1.5), IPA_ERR_SETTING);
            assert_eq!(
                ipa_hrls_init(p, len, 3, 1, 1, 1.0, 1e6, -1.0, 1.0, 255.0, 0.0, 2),
                IPA_ERR_SETTING
            );
            assert_eq!(
                ipa_hrls_init(
                    p,
                    len,
                    3,
                    1,
                    1,
                    1.0,
                    1e6,
                    -1.0,
                    1.0,
                    255.0,
                    0.0,
                    IPA_FORM_UD
                ),
                IPA_OK
            );
            assert_eq!(ok(3, 1, 1, 1.0), IPA_OK);
            for _ in 0..3 {
                assert_eq!(
                    ipa_hrls_update(p, 5.0, 0.0, core::ptr::null_mut()),
                    IPA_PENDING
                );
            }
            let mut eps = f64::NAN;
            assert_eq!(ipa_hrls_update(p, 5.0, 2.0, &mut eps), IPA_OK);
            assert_eq!(eps, 2.0, "θ̂(0) = 0, so ε = y");
            assert_eq!(
                ipa_hrls_update(p, f64::NAN, 2.0, &mut eps),
                IPA_ERR_NOT_FINITE
            );
            let mut a = [0.0; 3];
            assert_eq!(ipa_hrls_a(p, a.as_mut_ptr(), 3), 3);
            assert_eq!(ipa_hrls_a(p, a.as_mut_ptr(), 2), IPA_ERR_LENGTH);
            let mut b = [0.0; 1];
            assert_eq!(ipa_hrls_b(p, b.as_mut_ptr(), 1), 1);
            assert_eq!(b[0], 1.0);
            let mut th = [0.0; 19];
            assert_eq!(ipa_hrls_theta(p, th.as_mut_ptr(), 19), 7);
            assert_eq!(ipa_hrls_deadzone(p, core::ptr::null_mut()), IPA_ERR_NULL);
        }
    }

    #[test]
    fn pi_and_compensator_through_the_c_interface() {
        let mut mem = [0u64; IPA_PI_STATE_BYTES / 8];
        let p = mem.as_mut_ptr() as *mut c_void;
        let mut u = 0.0;
        unsafe {
            assert_eq!(
                ipa_pi_init(p, IPA_PI_STATE_BYTES, 14.0, 1.0, 0.01, 255.0, 3, 0.0),
                IPA_ERR_SETTING
            );
            assert_eq!(
                ipa_pi_init(p, IPA_PI_STATE_BYTES, 14.0, 1.0, 0.01, 255.0, 1, 0.0),
                IPA_OK
            );
            assert_eq!(ipa_pi_step(p, 1.0, 0.0, &mut u), IPA_OK);
            assert!((u - 14.01).abs() < 1e-12);
            // A plausibility range: crossed is refused (none set: y = −1e6 still taken by a copy),
            // [0, 200] is kept and refuses y = −1e6 with u untouched.
            assert_eq!(ipa_pi_set_range(p, 200.0, 0.0), IPA_ERR_SETTING);
            let mut copy = mem;
            let c = copy.as_mut_ptr() as *mut c_void;
            assert_eq!(ipa_pi_step(c, 1.0, -1e6, &mut u), IPA_OK);
            assert_eq!(ipa_pi_set_range(p, 0.0, 200.0), IPA_OK);
            u = 42.0;
            assert_eq!(ipa_pi_step(p, 1.0, -1e6, &mut u), IPA_ERR_RANGE);
            assert_eq!(u, 42.0);
            assert_eq!(
                ipa_pi_set_range(core::ptr::null_mut(), 0.0, 1.0),
                IPA_ERR_NULL
            );
            let dz = IpaDeadzone {
                b_l: -20.0,
                b_r: 30.0,
                m_l: 1.0,
                m_r: 1.0,
            };
            assert_eq!(ipa_dz_compensate(&dz, 0, 0.0, 255.0, 10.0, &mut u), IPA_OK);
            assert_eq!(u, 40.0);
            let bad = IpaDeadzone { m_r: -1.0, ..dz };
            assert_eq!(
                ipa_dz_compensate(&bad, 0, 0.0, 255.0, 10.0, &mut u),
                IPA_ERR_SETTING
            );
        }
    }
}
