//! Audit s33 H-2: one finite garbage position sample corrupted the recursive Hammerstein estimator
//! for good, and `ipa_hrls_deadzone` then returned IPA_OK with slopes of 1e302. The auditor's scenario
//! (c/glitch.c): docs/embedded.md's setup (na = 3, nb = 1, nk = 1, p0 = 1e6, b_l0 = −1, b_r0 = 1,
//! limit = 255, no guard, UD form), a Hammerstein plant with the deadzone b_l = −40, b_r = 40,
//! m_l = 0.012, m_r = 0.01 and A = 1 − 1.5 q⁻¹ + 0.7 q⁻² − 0.1 q⁻³ (so y(k) = 1.5 y(k−1) −
//! 0.7 y(k−2) + 0.1 y(k−3) + x(k−1) + noise), random commands in [−200, 200] counts, 3000 good samples, ONE sample
//! whose y is a glitch G, then 6000 good samples. With a plausibility range the glitch is refused
//! (`Error::OutOfRange`, the state unchanged) and the run ends bit for bit as one that never saw it;
//! without one every finite sample is taken, as before. `plausible_deadzone` (the rule of
//! `ipa_hrls_deadzone`) refuses the absurd estimates.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use ipa_embedded::hammerstein::PaperHrls;
use ipa_embedded::{Deadzone, Error, Form, HammersteinSettings, Implausible};

/// The true deadzone of the auditor's plant.
const TRUTH: Deadzone<f64> = Deadzone {
    b_l: -40.0,
    b_r: 40.0,
    m_l: 0.012,
    m_r: 0.01,
};
/// The true a_1..a_3.
const A: [f64; 3] = [-1.5, 0.7, -0.1];
/// The glitch comes at this sample.
const K_GLITCH: usize = 3000;
/// The range used: a stroke of ±100 mm (the plant's output stays within ±25 mm: checked below).
const RANGE: (f64, f64) = (-100.0, 100.0);

/// The auditor's settings with forgetting ρ.
fn settings(rho: f64) -> HammersteinSettings<f64> {
    HammersteinSettings {
        forgetting: rho,
        form: Form::Ud,
        ..HammersteinSettings::paper()
    }
}

/// 9000 samples (u(k), y(k)) of the plant, noise ±0.001 mm from a fixed LCG.
fn record() -> Vec<(f64, f64)> {
    let mut seed = 7u64;
    let mut next = || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        seed >> 33
    };
    let (mut y_past, mut u1) = ([0.0f64; 3], 0.0);
    (0..9000)
        .map(|_| {
            let u = (next() % 401) as f64 - 200.0;
            let noise = 0.001 * ((next() % 1000) as f64 / 500.0 - 1.0);
            let y =
                -A[0] * y_past[0] - A[1] * y_past[1] - A[2] * y_past[2] + TRUTH.apply(u1) + noise;
            y_past = [y, y_past[0], y_past[1]];
            u1 = u;
            (u, y)
        })
        .collect()
}

/// Every bit of the estimator's state that an update can change: θ̂, P (or its factors' product),
/// the sample count and the switching deadzone.
fn bits(est: &PaperHrls<f64>) -> Vec<u64> {
    let n = est.rls().n_params();
    let mut v: Vec<u64> = est.theta().iter().map(|t| t.to_bits()).collect();
    for i in 0..n {
        for j in 0..n {
            v.push(est.rls().p(i, j).to_bits());
        }
    }
    let d = est.switching_deadzone();
    v.extend([d.b_l, d.b_r, d.m_l, d.m_r].map(f64::to_bits));
    v.push(est.samples() as u64);
    v
}

/// What the glitch's update returned (`None`: no glitch given).
type AtGlitch = Option<Result<Option<f64>, Error>>;

/// Feeds the record with the sample at K_GLITCH replaced by (u, `glitch`) (`None`: skipped, as if
/// never given); returns the result of the glitch's update and how many of the others failed.
fn run(est: &mut PaperHrls<f64>, data: &[(f64, f64)], glitch: Option<f64>) -> (AtGlitch, usize) {
    let (mut at_glitch, mut failed) = (None, 0);
    for (k, &(u, y)) in data.iter().enumerate() {
        if k == K_GLITCH {
            let Some(g) = glitch else { continue };
            let before = bits(est);
            let r = est.update(u, g);
            if r.is_err() {
                assert_eq!(
                    bits(est),
                    before,
                    "a refused sample leaves the state unchanged"
                );
            }
            at_glitch = Some(r);
            continue;
        }
        failed += usize::from(est.update(u, y).is_err());
    }
    (at_glitch, failed)
}

/// The estimate is the plant's: breakpoints within 0.5 counts, slopes within 2 %, a_1 within 0.01.
fn near_truth(est: &PaperHrls<f64>) -> bool {
    let d = est.deadzone();
    (d.b_l - TRUTH.b_l).abs() < 0.5
        && (d.b_r - TRUTH.b_r).abs() < 0.5
        && (d.m_l / TRUTH.m_l - 1.0).abs() < 0.02
        && (d.m_r / TRUTH.m_r - 1.0).abs() < 0.02
        && (est.theta()[4] - A[0]).abs() < 0.01
}

// The range is honest: every good sample lies well inside it.
#[test]
fn the_plants_output_lies_inside_the_range() {
    let data = record();
    let max = data.iter().map(|&(_, y)| y.abs()).fold(0.0, f64::max);
    assert!(max < 25.0 && max > 1.0, "{max}");
}

// With the range [−100, 100] mm the glitches y = 1000, −1e6 and 2e306 mm are refused with OutOfRange,
// the state unchanged bit for bit (checked in `run`), and after the 6000 good samples that follow the
// estimate is bit for bit that of a run that never saw the glitch (the refused sample is not counted
// and does not enter the delay lines), and the plant's: a deadzone to compensate with.
#[test]
fn a_glitch_is_refused_and_the_run_goes_on_as_without_it() {
    let data = record();
    for rho in [1.0, 0.99] {
        let ranged = || {
            PaperHrls::new(settings(rho))
                .unwrap()
                .with_range(RANGE.0, RANGE.1)
                .unwrap()
        };
        let mut clean = ranged();
        assert_eq!(run(&mut clean, &data, None), (None, 0));
        assert_eq!(clean.samples(), data.len() - 1);
        assert!(near_truth(&clean), "ρ = {rho}: {:?}", clean.deadzone());
        assert_eq!(clean.plausible_deadzone(), Ok(clean.deadzone()));
        for g in [1000.0, -1e6, 2e306] {
            let mut est = ranged();
            assert_eq!(
                run(&mut est, &data, Some(g)),
                (Some(Err(Error::OutOfRange)), 0)
            );
            assert_eq!(bits(&est), bits(&clean), "ρ = {rho}, G = {g}");
        }
    }
}

// Without a range every finite sample is taken, as before (the old behaviour, unchanged): the glitch's
// update succeeds, and with ρ = 1 (least squares, which never forgets a row) the one row with an
// error of 1000 mm among 9000 with errors of 0.001 mm leaves the estimate far from the plant after the
// 6000 good samples (the auditor: b_r 99.6, a_1 −0.065), a deadzone that may still look like a
// valve's: no rule on the estimate can tell it, only the range prevents it. With G = 2e306 and
// ρ = 0.99 the estimate diverges: the old rule called it a valve deadzone (finite, positive slopes),
// `plausible_deadzone` refuses it (|a_1| ≈ 5e303 > C(3, 1) 2 = 6).
#[test]
fn without_a_range_a_glitch_is_taken_and_an_absurd_estimate_is_refused() {
    let data = record();
    let mut est = PaperHrls::new(settings(1.0)).unwrap();
    assert!(matches!(
        run(&mut est, &data, Some(1000.0)),
        (Some(Ok(Some(_))), 0)
    ));
    assert_eq!(est.samples(), data.len());
    let d = est.deadzone();
    assert!(!near_truth(&est), "{d:?} a_1 {}", est.theta()[4]);
    assert!(
        (est.theta()[4] - A[0]).abs() > 0.1,
        "{d:?} a_1 {}",
        est.theta()[4]
    );

    let mut est = PaperHrls::new(settings(0.99)).unwrap();
    // Taken, and then (the auditor: 5999 of 5999) the later updates fail.
    let (at, failed) = run(&mut est, &data, Some(2e306));
    assert!(matches!(at, Some(Ok(Some(_)))), "{at:?}");
    assert!(failed > 5000, "{failed}");
    let d = est.deadzone();
    assert!(d.is_physical(), "the old rule's verdict: {d:?}");
    assert!(d.m_l > 1e250 && est.theta()[4].abs() > 1e250, "{d:?}");
    assert_eq!(est.plausible_deadzone(), Err(Implausible::Diverged));
    // The range may be set afterwards (θ̂ kept); the verdict stays a refusal.
    let est = est.with_range(RANGE.0, RANGE.1).unwrap();
    assert!(est.plausible_deadzone().is_err());
}

// With a range, a command beyond ±limit (255 counts) is refused too; without one it is taken. 255 itself
// is plausible (bounds included).
#[test]
fn a_command_beyond_the_limit_is_refused_with_a_range() {
    let mut est = PaperHrls::new(settings(1.0))
        .unwrap()
        .with_range(RANGE.0, RANGE.1)
        .unwrap();
    assert_eq!(est.update(255.5, 0.0), Err(Error::OutOfRange));
    assert_eq!(est.update(-1e300, 0.0), Err(Error::OutOfRange));
    assert_eq!(est.update(0.0, 100.5), Err(Error::OutOfRange));
    assert_eq!(est.samples(), 0);
    assert_eq!(est.update(255.0, 100.0), Ok(None));
    assert_eq!(est.update(-255.0, -100.0), Ok(None));
    let mut free = PaperHrls::new(settings(1.0)).unwrap();
    assert_eq!(free.update(1e6, 1e6), Ok(None));
    assert_eq!(free.samples(), 1);
}

// A range must be finite and ordered; a bad one is refused and the estimator keeps its range.
#[test]
fn a_bad_range_is_a_setting_error() {
    let est = PaperHrls::new(settings(1.0)).unwrap();
    assert_eq!(est.range(), None);
    for (lo, hi) in [
        (200.0, 0.0),
        (0.0, 0.0),
        (f64::NAN, 1.0),
        (0.0, f64::INFINITY),
    ] {
        assert_eq!(est.with_range(lo, hi).unwrap_err(), Error::Setting);
    }
    assert_eq!(
        est.with_range(-5.0, 205.0).unwrap().range(),
        Some((-5.0, 205.0))
    );
}

// The slope rule, derived by hand for the noise-free plant with slopes m_l = m_r = 2 mm/count (one full
// command of 255 counts gives x = 2 (255 − 40) = 430 mm in one sample): with the range [−5, 205] mm
// (span 210 < 430) the fitted deadzone is TooSteep; with [−500, 500] (span 1000 ≥ 430) and without a
// range it is kept. The estimate itself is the plant's (noise-free, exact switching).
#[test]
fn a_deadzone_steeper_than_the_range_allows_is_refused() {
    let steep = Deadzone {
        m_l: 2.0,
        m_r: 2.0,
        ..TRUTH
    };
    let mut est = PaperHrls::new(settings(0.98)).unwrap();
    let mut seed = 3u64;
    let (mut y_past, mut u1) = ([0.0f64; 3], 0.0);
    for _ in 0..4000 {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let u = ((seed >> 33) % 401) as f64 - 200.0;
        let y = -A[0] * y_past[0] - A[1] * y_past[1] - A[2] * y_past[2] + steep.apply(u1);
        y_past = [y, y_past[0], y_past[1]];
        u1 = u;
        est.update(u, y).unwrap();
    }
    let d = est.deadzone();
    assert!(
        (d.m_r - 2.0).abs() < 1e-6 && (d.b_r - 40.0).abs() < 1e-4,
        "{d:?}"
    );
    assert_eq!(est.plausible_deadzone(), Ok(d));
    let narrow = est.with_range(-5.0, 205.0).unwrap();
    assert_eq!(narrow.plausible_deadzone(), Err(Implausible::TooSteep));
    let wide = est.with_range(-500.0, 500.0).unwrap();
    assert_eq!(wide.plausible_deadzone(), Ok(d));
}

// The pole bound |a_i| ≤ C(na, i) 2^i is met by every A whose roots lie in |z| ≤ 2 and is not by one
// with a root beyond: A = (1 − 0.9 z⁻¹)³ (a = −2.7, 2.43, −0.729; bounds 6, 12, 8) and the plant's
// A pass; the estimator starts at θ̂ = 0 (a = 0), which passes. Checked through a noise-free plant with
// A = (1 − 0.9 z⁻¹)³ (stable), whose fitted deadzone must be kept.
#[test]
fn a_stable_plant_with_large_coefficients_passes_the_pole_bound() {
    let a = [-2.7, 2.43, -0.729];
    let mut est = PaperHrls::new(settings(0.98)).unwrap();
    let mut seed = 11u64;
    let (mut y_past, mut u1) = ([0.0f64; 3], 0.0);
    for _ in 0..4000 {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let u = ((seed >> 33) % 401) as f64 - 200.0;
        let y = -a[0] * y_past[0] - a[1] * y_past[1] - a[2] * y_past[2] + TRUTH.apply(u1);
        y_past = [y, y_past[0], y_past[1]];
        u1 = u;
        est.update(u, y).unwrap();
    }
    let t = est.theta();
    assert!((t[4] - a[0]).abs() < 1e-6, "{t:?}");
    assert_eq!(est.plausible_deadzone(), Ok(est.deadzone()));
}

/// Audit s33 M-3's record: the plant excited for 2000 samples, at rest for `rest` samples (u = 0,
/// y held), then excited for 6000 samples.
fn rest_record(rest: usize) -> Vec<(f64, f64)> {
    let mut seed = 3u64;
    let (mut y_past, mut u1) = ([0.0f64; 3], 0.0);
    (0..2000 + rest + 6000)
        .map(|k| {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let at_rest = (2000..2000 + rest).contains(&k);
            let u = if at_rest {
                0.0
            } else {
                ((seed >> 33) % 401) as f64 - 200.0
            };
            let y = if at_rest {
                y_past[0]
            } else {
                -A[0] * y_past[0] - A[1] * y_past[1] - A[2] * y_past[2] + TRUTH.apply(u1)
            };
            y_past = [y, y_past[0], y_past[1]];
            u1 = u;
            (u, y)
        })
        .collect()
}

// Audit s33 M-3 (docs/embedded.md's old example: ρ < 1, no guard): at rest φ excites no deadzone
// column, so P grows by 1/ρ per sample there; with ρ = 0.98 and p0 = 1e6 it passes f64's 1.8e308 after
// ln(1.8e302)/ln(1/0.98) ≈ 34 430 samples at the latest, so a rest of 40 000 samples ends in
// Error::Numerical (or, eq. 12, Error::Indefinite), which then repeats on every one of the 6000 exciting samples after it. Restarting
// the covariance on the error (what the docs now say to do) recovers the plant (at most one failed
// update after the excitation resumes, the one that restarts); a trace guard
// (max_trace = p0 n = 7e6, identify's default) prevents it.
#[test]
fn covariance_windup_repeats_until_a_restart_and_a_guard_prevents_it() {
    let data = rest_record(40_000);
    let resumed = data.len() - 6000;
    let s = HammersteinSettings {
        forgetting: 0.98,
        ..HammersteinSettings::paper()
    };
    for form in [Form::Standard, Form::Ud] {
        let s = HammersteinSettings { form, ..s };
        // No guard, no restart: every update after the excitation resumes fails.
        let mut est = PaperHrls::new(s).unwrap();
        let failed: Vec<bool> = data
            .iter()
            .map(|&(u, y)| est.update(u, y).is_err())
            .collect();
        assert!(failed[..2000].iter().all(|f| !f), "{form:?}");
        assert!(failed[resumed..].iter().all(|&f| f), "{form:?}");
        // Restart on Numerical: the 6000 exciting samples bring the plant back.
        let mut est = PaperHrls::new(s).unwrap();
        let mut failed_after = 0;
        for (k, &(u, y)) in data.iter().enumerate() {
            // Eq. 12 meets the wound-up P as Indefinite (ρ + φᵀPφ ≤ 0) or Numerical (overflow).
            if matches!(est.update(u, y), Err(Error::Numerical | Error::Indefinite)) {
                est.restart_covariance();
                failed_after += usize::from(k >= resumed);
            }
        }
        // At most the one failure that triggers the restart (the first exciting sample may meet the
        // wound-up P), not the 6000 of the run without it.
        assert!(failed_after <= 1, "{form:?}: {failed_after}");
        assert!(near_truth(&est), "{form:?}: {:?}", est.deadzone());
        // The guard: no update fails at all.
        let guarded = HammersteinSettings {
            max_trace: Some(7e6),
            ..s
        };
        let mut est = PaperHrls::new(guarded).unwrap();
        assert!(
            data.iter().all(|&(u, y)| est.update(u, y).is_ok()),
            "{form:?}"
        );
        assert!(near_truth(&est), "{form:?}: {:?}", est.deadzone());
    }
}

/// The noise-free plant of this file with the deadzone `truth`, fed to an estimator with forgetting
/// 0.98 (the early rows, switched by a wrong early deadzone, are forgotten) and command limit `limit`
/// (no range): random commands in [−200, 200] counts, 6000 samples.
fn fed(truth: Deadzone<f64>, limit: f64) -> PaperHrls<f64> {
    let mut est = PaperHrls::new(HammersteinSettings {
        limit,
        ..settings(0.98)
    })
    .unwrap();
    let mut seed = 11u64;
    let (mut y_past, mut u1) = ([0.0f64; 3], 0.0);
    for _ in 0..6000 {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let u = ((seed >> 33) % 401) as f64 - 200.0;
        let y = -A[0] * y_past[0] - A[1] * y_past[1] - A[2] * y_past[2] + truth.apply(u1);
        y_past = [y, y_past[0], y_past[1]];
        u1 = u;
        est.update(u, y).unwrap();
    }
    est
}

// One rounding rule for the estimator and the compensators (brief fix34 item 4; s33 leftover:
// `ipa_hrls_deadzone` called b_l = +1e-18 IPA_NOT_PHYSICAL while the compensators took it as 0). The
// tolerance is 1e-9 · limit = 2.55e-7 counts at limit = 255. A plant whose left breakpoint is
// b_l = +1e-12 counts (inside it; noise-free, so the estimate is the plant's to rounding, ~1e-14) is
// kept by `plausible_deadzone` at limit 255 with b_l taken as 0, and `Compensator::new` at u_max = 255
// accepts the same estimate; with an infinite limit there is no tolerance (the documented rule; a
// compensator has no infinite u_max): refused, NotPhysical. A plant with b_l = +1e-3 counts (beyond
// the tolerance) is refused by both at 255.
#[test]
fn the_estimator_rounds_breakpoints_as_the_compensators_do() {
    use ipa_embedded::{Compensator, SlopeMode};
    let tiny = Deadzone {
        b_l: 1e-12,
        ..TRUTH
    };
    let est = fed(tiny, 255.0);
    let raw = est.deadzone();
    assert!(
        raw.b_l > 0.0 && raw.b_l <= 1e-9 * 255.0 && (raw.b_r - 40.0).abs() < 1e-6,
        "the estimate is the plant's: {raw:?}"
    );
    let kept = est
        .plausible_deadzone()
        .expect("b_l within 1e-9 · limit of 0");
    assert_eq!(kept.b_l, 0.0);
    assert_eq!((kept.b_r, kept.m_l, kept.m_r), (raw.b_r, raw.m_l, raw.m_r));
    let comp = Compensator::new(raw, SlopeMode::Shift, 0.0, 255.0).expect("the compensator too");
    assert_eq!(comp.deadzone(), kept);

    let unbounded = fed(tiny, f64::INFINITY);
    assert_eq!(
        unbounded.deadzone(),
        raw,
        "the limit does not change the updates"
    );
    assert_eq!(
        unbounded.plausible_deadzone(),
        Err(Implausible::NotPhysical)
    );

    let beyond = fed(Deadzone { b_l: 1e-3, ..TRUTH }, 255.0);
    let d = beyond.deadzone();
    assert!((d.b_l - 1e-3).abs() < 1e-9, "{d:?}");
    assert_eq!(beyond.plausible_deadzone(), Err(Implausible::NotPhysical));
    assert_eq!(
        Compensator::new(d, SlopeMode::Shift, 0.0, 255.0),
        Err(Error::Setting)
    );
}
