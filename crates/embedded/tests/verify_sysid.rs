//! The embedded f64 estimator against `sysid`'s recursive identification (`identify --method rls
//! --passes 1`, what the command line runs) on the same records: bit-for-bit equal models, because the
//! operations and their order are the same. With the trace windup guard `sysid` writes the update in a
//! different order (`RobustRls`), so there the models agree to rounding (1e-9 relative). The f32
//! estimator is checked against the f64 one to a stated tolerance.
//!
//! The UD form (`--rls-form ud`) is bit for bit equal to sysid's too, with and without the guard, and is
//! the form that works in f32.
//!
//! This file keeps its use of the `sysid` API to `Dataset::new`, `Identification` and `identify`.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use ipa_embedded::hammerstein::{HammersteinRls, HammersteinSettings};
use ipa_embedded::{Deadzone, Form};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sysid::data::Signals;
use sysid::{identify, EstimatorSettings, Identification, RecursiveLeastSquares};

/// A record of a Hammerstein plant: the paper's A(q) (near-integrator), deadzone b_l = −25, b_r = 20
/// counts, the key-term slopes of docs/paper.md §2.3, and white output-equation noise N(0, σ²) mm;
/// staircase input of random levels held 40 samples, both signs unless `one_sided`.
fn record(n: usize, seed: u64, sigma: f64, one_sided: bool) -> (Vec<f64>, Vec<f64>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let dz = Deadzone {
        b_l: -25.0,
        b_r: 20.0,
        m_l: 5.42182e-3,
        m_r: 3.72946e-3,
    };
    let (a1, a2, a3) = (-1.869, 0.9976, -0.1284);
    let mut u = vec![0.0; n];
    let mut y = vec![0.0; n];
    let mut level = 0.0;
    for k in 0..n {
        if k % 40 == 0 {
            level = f64::from(rng.gen_range(-255i32..=255));
            if one_sided {
                level = level.abs();
            }
            // Keep the stroke bounded (two-sided records): push back towards the middle.
            if !one_sided && k > 3 && y[k - 1] > 80.0 {
                level = -level.abs();
            }
            if !one_sided && k > 3 && y[k - 1] < -80.0 {
                level = level.abs();
            }
        }
        u[k] = level;
        if k >= 3 {
            let (u1, u2) = (rng.gen::<f64>().max(1e-300), rng.gen::<f64>());
            let e = sigma * (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
            y[k] = -a1 * y[k - 1] - a2 * y[k - 2] - a3 * y[k - 3] + dz.apply(u[k - 1]) + e;
        }
    }
    (u, y)
}

struct Fit {
    dz: [f64; 4],
    a: Vec<f64>,
    b: Vec<f64>,
}

fn sysid_fit(
    u: &[f64],
    y: &[f64],
    orders: (usize, usize, usize),
    rho: f64,
    max_trace: Option<f64>,
) -> Fit {
    sysid_fit_form(u, y, orders, rho, max_trace, Form::Standard)
}

fn sysid_fit_form(
    u: &[f64],
    y: &[f64],
    (na, nb, nk): (usize, usize, usize),
    rho: f64,
    max_trace: Option<f64>,
    form: Form,
) -> Fit {
    let data = sysid::Dataset::new(
        Signals {
            u: u.to_vec(),
            y: y.to_vec(),
        },
        0.01,
        "verify",
    )
    .unwrap();
    let mut rls = RecursiveLeastSquares {
        forgetting: rho,
        passes: sysid::Passes::Fixed(1), // the paper's single pass, as the embedded estimator runs
        ..RecursiveLeastSquares::default()
    };
    if let Some(t) = max_trace {
        rls.windup = sysid::windup::Windup::Trace;
        rls.max_trace = Some(t);
    }
    if form == Form::Ud {
        rls.form = sysid::rls_ud::RlsForm::Ud;
    }
    let s = Identification {
        drop_unexcited_branch: true, // as the command line does
        fallback: false,             // the estimator's own result, whatever its quality
        ..Identification::default()
    }
    .with_orders(na, nb, nk)
    .with_estimator(EstimatorSettings::Rls(rls));
    let m = identify(&data, &s).unwrap().model;
    let d = *m.deadzone().unwrap();
    Fit {
        dz: [d.b_l, d.b_r, d.m_l, d.m_r],
        a: m.a().to_vec(),
        b: m.b().to_vec(),
    }
}

fn embedded_fit<F: ipa_embedded::Float>(
    u: &[f64],
    y: &[f64],
    (na, nb, nk): (usize, usize, usize),
    rho: f64,
    max_trace: Option<f64>,
) -> Fit {
    embedded_fit_p0::<F>(u, y, (na, nb, nk), rho, max_trace, 1e6, Form::Standard).unwrap()
}

fn embedded_fit_p0<F: ipa_embedded::Float>(
    u: &[f64],
    y: &[f64],
    (na, nb, nk): (usize, usize, usize),
    rho: f64,
    max_trace: Option<f64>,
    p0: f64,
    form: Form,
) -> Result<Fit, ipa_embedded::Error> {
    let uf: Vec<F> = u.iter().map(|v| F::from_f64(*v)).collect();
    let mut s = HammersteinSettings::<F>::paper().from_record(&uf);
    s.na = na;
    s.nb = nb;
    s.nk = nk;
    s.forgetting = F::from_f64(rho);
    s.max_trace = max_trace.map(F::from_f64);
    s.p0 = F::from_f64(p0);
    s.form = form;
    let mut est = HammersteinRls::<F, 19, 15>::new(s)?;
    for (uk, yk) in uf.iter().zip(y) {
        est.update(*uk, F::from_f64(*yk))?;
    }
    let d = est.deadzone();
    let mut a = vec![F::ZERO; na];
    let mut b = vec![F::ZERO; nb];
    est.a(&mut a)?;
    est.b(&mut b)?;
    Ok(Fit {
        dz: [d.b_l, d.b_r, d.m_l, d.m_r].map(|v| v.to_f64()),
        a: a.iter().map(|v| v.to_f64()).collect(),
        b: b.iter().map(|v| v.to_f64()).collect(),
    })
}

fn all(f: &Fit) -> Vec<f64> {
    f.dz.iter().chain(&f.a).chain(&f.b).copied().collect()
}

const ORDERS: [(usize, usize, usize); 4] = [(3, 1, 1), (2, 2, 1), (3, 2, 2), (1, 3, 0)];

// Two-sided records, four structures, ρ = 1 and 0.99: every parameter bit for bit.
#[test]
fn f64_estimator_is_bit_for_bit_sysid_rls_first_pass() {
    for (seed, orders) in ORDERS.iter().enumerate() {
        let (u, y) = record(3000, seed as u64, 0.01, false);
        for rho in [1.0, 0.99] {
            let want = sysid_fit(&u, &y, *orders, rho, None);
            let got = embedded_fit::<f64>(&u, &y, *orders, rho, None);
            assert!(want.dz.iter().all(|v| *v != 0.0), "{:?}", want.dz);
            for (w, g) in all(&want).iter().zip(all(&got)) {
                assert_eq!(
                    w.to_bits(),
                    g.to_bits(),
                    "{orders:?} ρ={rho}: {w:e} vs {g:e}"
                );
            }
        }
    }
}

// A record that is never negative: `identify` drops the left branch (m_l = b_l = 0); the embedded
// estimator starts it at b_l0 = −∞, so its columns stay zero, and gives the same model bit for bit.
#[test]
fn one_sided_record_matches_the_dropped_branch() {
    let (u, y) = record(3000, 7, 0.01, true);
    assert!(u.iter().all(|v| *v >= 0.0));
    let want = sysid_fit(&u, &y, (3, 1, 1), 1.0, None);
    let got = embedded_fit::<f64>(&u, &y, (3, 1, 1), 1.0, None);
    assert_eq!((want.dz[0], want.dz[2]), (0.0, 0.0));
    for (w, g) in all(&want).iter().zip(all(&got)) {
        assert_eq!(w.to_bits(), g.to_bits(), "{w:e} vs {g:e}");
    }
}

// Windup guard tr P ≤ T = 1 at ρ = 0.98 (the bound is active and changes the estimate by about 5 %
// against the unguarded one): the same model as `identify --windup trace` to 1e-9 relative (measured:
// 3e-11) (the two implementations round differently: sysid's guarded update divides by ρ + φᵀPφ per
// entry and sums ε as y − Σ, the embedded one multiplies by the inverse as the paper's unguarded RLS).
#[test]
fn trace_guard_matches_sysid_windup_trace_to_rounding() {
    let (u, y) = record(3000, 11, 0.01, false);
    let want = sysid_fit(&u, &y, (3, 1, 1), 0.98, Some(1.0));
    let got = embedded_fit::<f64>(&u, &y, (3, 1, 1), 0.98, Some(1.0));
    let unguarded = embedded_fit::<f64>(&u, &y, (3, 1, 1), 0.98, None);
    let mut differs = false;
    for ((w, g), q) in all(&want).iter().zip(all(&got)).zip(all(&unguarded)) {
        assert!(
            (w - g).abs() <= 1e-9 * w.abs().max(g.abs()),
            "{w:e} vs {g:e}"
        );
        differs |= (q - g).abs() > 1e-2 * g.abs();
    }
    assert!(differs, "the guard must change the estimate on this record");
}

// f32 (single-precision FPU). The paper's covariance-form RLS is fragile in f32 on this near-integrator
// (the columns −y(k−1), −y(k−2), −y(k−3) are nearly collinear): measured on these records, it loses
// positive definiteness for p0 ≥ 1e2 at ρ = 1 on most records and for every p0 tried (1 to 1e6) at
// ρ = 0.99. That is reported as `Error::Indefinite` (ρ + φᵀPφ ≤ 0 with finite values; never a NaN
// estimate). With p0 = 1 and ρ = 1 it works
// and stays close to the f64 estimator started the same way (a start that regularises the estimate
// noticeably): breakpoints within 0.1 count, slopes within 0.1 %, a within 1e-4.
#[test]
fn f32_estimator_is_close_to_f64_where_it_works_and_fails_loudly_where_not() {
    for seed in [3, 4, 5] {
        let (u, y) = record(3000, seed, 0.01, false);
        let d = embedded_fit_p0::<f64>(&u, &y, (3, 1, 1), 1.0, None, 1.0, Form::Standard).unwrap();
        let s = embedded_fit_p0::<f32>(&u, &y, (3, 1, 1), 1.0, None, 1.0, Form::Standard).unwrap();
        assert!(
            (d.dz[0] - s.dz[0]).abs() < 0.1 && (d.dz[1] - s.dz[1]).abs() < 0.1,
            "{:?} {:?}",
            d.dz,
            s.dz
        );
        assert!((d.dz[2] / s.dz[2] - 1.0).abs() < 1e-3 && (d.dz[3] / s.dz[3] - 1.0).abs() < 1e-3);
        for (p, q) in d.a.iter().zip(&s.a) {
            assert!((p - q).abs() < 1e-4, "{p} vs {q}");
        }
        let e = embedded_fit_p0::<f32>(&u, &y, (3, 1, 1), 0.99, None, 1.0, Form::Standard);
        assert_eq!(e.err(), Some(ipa_embedded::Error::Indefinite));
        let e = embedded_fit_p0::<f32>(&u, &y, (3, 1, 1), 1.0, None, 1e6, Form::Standard);
        assert_eq!(e.err(), Some(ipa_embedded::Error::Indefinite));
    }
}

// UD form (`identify --rls-form ud`), with and without the trace guard: the same operations in the same
// order as sysid's Bierman update, so every parameter is equal (`==`: bit for bit up to the sign of zero).
#[test]
fn ud_form_is_bit_for_bit_sysid_rls_form_ud() {
    for (seed, orders) in ORDERS.iter().enumerate() {
        let (u, y) = record(3000, 20 + seed as u64, 0.01, false);
        for (rho, t) in [(1.0, None), (0.99, None), (0.98, Some(1.0))] {
            let want = sysid_fit_form(&u, &y, *orders, rho, t, Form::Ud);
            let got = embedded_fit_p0::<f64>(&u, &y, *orders, rho, t, 1e6, Form::Ud).unwrap();
            for (w, g) in all(&want).iter().zip(all(&got)) {
                assert!(*w == g, "{orders:?} ρ={rho} T={t:?}: {w:e} vs {g:e}");
            }
        }
    }
}

// The UD form is the remedy in f32: on 20 records (seeds 0–19), with the defaults p0 = 1e6 and ρ = 1 or
// 0.99 (where eq. 12 in f32 fails), it runs through and stays close to the f64 UD estimate. f32 rounding
// moves the breakpoints by a few thousandths of a count on most records and by a few tenths on a few
// ill-conditioned ones (which records depends on the exact rounding sequence: over seeds 0–59, the median
// |Δb| was 0.006 count both with Bierman's divisions and with the reciprocals used since issue 28, the
// largest 0.35 and 0.62 count; here, seeds 0–19: median 0.006, all but one ≤ 0.04, the one (seed 3,
// ρ = 0.99) 0.62 count with slopes 4e-3 relative and a 2e-4 off). So: every breakpoint within 1 count
// (the command's resolution), slopes within 1e-2 relative, a within 1e-3, and the median breakpoint
// difference below 0.02 count.
#[test]
fn f32_ud_form_works_where_the_standard_form_fails() {
    let mut db = Vec::new();
    for seed in 0..20 {
        let (u, y) = record(3000, seed, 0.01, false);
        for rho in [1.0, 0.99] {
            let d = embedded_fit_p0::<f64>(&u, &y, (3, 1, 1), rho, None, 1e6, Form::Ud).unwrap();
            let s = embedded_fit_p0::<f32>(&u, &y, (3, 1, 1), rho, None, 1e6, Form::Ud).unwrap();
            let diff = (d.dz[0] - s.dz[0]).abs().max((d.dz[1] - s.dz[1]).abs());
            assert!(diff < 1.0, "seed {seed} ρ={rho}: {:?} {:?}", d.dz, s.dz);
            db.push(diff);
            assert!(
                (d.dz[2] / s.dz[2] - 1.0).abs() < 1e-2 && (d.dz[3] / s.dz[3] - 1.0).abs() < 1e-2
            );
            for (p, q) in d.a.iter().zip(&s.a) {
                assert!((p - q).abs() < 1e-3, "{p} vs {q}");
            }
            if !(3..=5).contains(&seed) {
                continue; // eq. 12 in f32 is shown to fail on three of the records
            }
            let standard =
                embedded_fit_p0::<f32>(&u, &y, (3, 1, 1), rho, None, 1e6, Form::Standard);
            assert_eq!(standard.err(), Some(ipa_embedded::Error::Indefinite));
        }
    }
    db.sort_by(f64::total_cmp);
    let median = db[db.len() / 2];
    assert!(median < 0.02, "median breakpoint difference {median} count");
}

// The UD guard acting and idle in turn (the pending scale ρ̃ set, then dropped): excitation, a quiet
// stretch (φ ≈ 0, so P grows like ρ^(−k) until tr P meets T), excitation again, on the state sized
// exactly (n = N = 4, the unrolled kernel) and on a larger state (n = 4, N = 9, run-time loop bounds).
// Every update: ε, θ̂ and tr P (its even-i plus odd-i column sums) equal to `sysid::rls_ud::RobustRls`'s
// (`--rls-form ud --windup trace`) bit for bit; the guard acted on some updates and not on others, and
// of the idle updates some ended near the bound (T/4 < tr P ≤ T: the update writes ρ̃ by a select) and
// some far from it (tr P ≤ T/4: a branch), the two ways the embedded update writes ρ̃ (issue 28,
// fifteenth round).
#[test]
fn ud_guard_switching_on_and_off_is_bit_for_bit_sysid() {
    use sysid::rls_ud::{RlsForm, RobustRls};
    use sysid::windup::Windup;
    let (rho, p0, t) = (0.95, 10.0, 100.0);
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut want = RobustRls::new(4, rho, p0, RlsForm::Ud, Windup::Trace, Some(t)).unwrap();
    let mut exact = ipa_embedded::Rls::<f64, 4>::new(4, rho, p0)
        .unwrap()
        .with_form(Form::Ud)
        .with_max_trace(t)
        .unwrap();
    let mut larger = ipa_embedded::Rls::<f64, 9>::new(4, rho, p0)
        .unwrap()
        .with_form(Form::Ud)
        .with_max_trace(t)
        .unwrap();
    let (mut acted, mut idle, mut near, mut far) = (0, 0, 0, 0);
    for k in 0..600 {
        let quiet = (150..350).contains(&(k % 400));
        let scale = if quiet { 1e-9 } else { 1.0 };
        let phi: Vec<f64> = (0..4).map(|_| scale * rng.gen_range(-1.0..1.0)).collect();
        let y = 2.0 * phi[0] - phi[1] + 0.5 * phi[2] + 0.25 * phi[3] + 1e-3 * rng.gen::<f64>();
        let e_want = want.update(&phi, y, k).unwrap();
        for est in [&mut exact as &mut dyn UdUpdate, &mut larger] {
            let (e, theta, tr) = est.step(&phi, y);
            assert!(e == e_want, "k={k}: ε {e:e} vs {e_want:e}");
            for (g, w) in theta.iter().zip(want.theta.iter()) {
                assert!(g == w, "k={k}: θ̂ {g:e} vs {w:e}");
            }
            assert!(
                tr == want.trace(),
                "k={k}: tr P {tr:e} vs {:e}",
                want.trace()
            );
        }
        // Acting: tr P was scaled to T (to rounding); else it is below T.
        if (want.trace() / t - 1.0).abs() < 1e-12 {
            acted += 1;
        } else {
            idle += 1;
            if want.trace() > t / 4.0 {
                near += 1;
            } else {
                far += 1;
            }
        }
    }
    assert!(acted > 10 && idle > 10, "guard acted {acted}, idle {idle}");
    assert!(
        near > 10 && far > 10,
        "idle near the bound {near}, far from it {far}"
    );
}

/// One UD update of an `ipa_embedded::Rls` of any capacity: ε, θ̂'s first four entries and tr P.
trait UdUpdate {
    fn step(&mut self, phi: &[f64], y: f64) -> (f64, Vec<f64>, f64);
}

impl<const N: usize> UdUpdate for ipa_embedded::Rls<f64, N> {
    fn step(&mut self, phi: &[f64], y: f64) -> (f64, Vec<f64>, f64) {
        let e = self.update(phi, y).unwrap();
        (e, self.theta()[..4].to_vec(), self.trace())
    }
}

// The UD update with n = N = 9 (the written-out kernel of a capacity ≥ 8, whose gain sweep computes the
// new U before pass 2 copies it: issue 28, sixteenth round), with and without the trace guard, through
// excitation and quiet stretches: bit for bit with `sysid::rls_ud::RobustRls` (ε, every θ̂_i, tr P).
#[test]
fn ud_form_with_nine_parameters_is_bit_for_bit_sysid() {
    use sysid::rls_ud::{RlsForm, RobustRls};
    use sysid::windup::Windup;
    let (rho, p0) = (0.97, 10.0);
    for guard in [None, Some(60.0)] {
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let windup = if guard.is_some() {
            Windup::Trace
        } else {
            Windup::None
        };
        let mut want = RobustRls::new(9, rho, p0, RlsForm::Ud, windup, guard).unwrap();
        let mut got = ipa_embedded::Rls::<f64, 9>::new(9, rho, p0)
            .unwrap()
            .with_form(Form::Ud);
        if let Some(t) = guard {
            got = got.with_max_trace(t).unwrap();
        }
        let mut acted = 0;
        for k in 0..800 {
            let quiet = (150..350).contains(&(k % 400));
            let scale = if quiet { 1e-9 } else { 1.0 };
            let phi: Vec<f64> = (0..9).map(|_| scale * rng.gen_range(-1.0..1.0)).collect();
            let y = phi
                .iter()
                .enumerate()
                .map(|(i, p)| p / (1.0 + i as f64))
                .sum::<f64>()
                + 1e-3 * rng.gen::<f64>();
            let e_want = want.update(&phi, y, k).unwrap();
            let e = got.update(&phi, y).unwrap();
            assert!(e == e_want, "T={guard:?} k={k}: ε {e:e} vs {e_want:e}");
            for (g, w) in got.theta().iter().zip(want.theta.iter()) {
                assert!(g == w, "T={guard:?} k={k}: θ̂ {g:e} vs {w:e}");
            }
            assert!(
                got.trace() == want.trace(),
                "T={guard:?} k={k}: tr P {:e} vs {:e}",
                got.trace(),
                want.trace()
            );
            if let Some(t) = guard {
                if (want.trace() / t - 1.0).abs() < 1e-12 {
                    acted += 1;
                }
            }
        }
        if guard.is_some() {
            assert!(acted > 10, "guard acted {acted} times");
        }
    }
}
