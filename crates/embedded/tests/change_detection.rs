//! Change detection (issue 15 part 4) on records made here: the recursive Hammerstein estimator's
//! prediction errors into the CUSUM detector. A valve whose deadzone and slopes change in the middle of
//! a record is flagged within a few hundred samples of the change and not before; a stationary record
//! of 50 000 samples raises no alarm; and the detector's run length on white noise agrees with an
//! independent Markov-chain computation.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use ipa_embedded::cusum::{Cusum, CusumStatus};
use ipa_embedded::hammerstein::{HammersteinSettings, PaperHrls};
use ipa_embedded::Deadzone;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Standard normal sample (rand_distr).
fn gauss(rng: &mut ChaCha8Rng) -> f64 {
    rng.sample(rand_distr::StandardNormal)
}

/// The paper's A(q) with a deadzone that becomes `after` from sample `change` on; σ = 0.01 mm white
/// equation noise; staircase input, random levels in ±255 held 40 samples.
fn record(n: usize, seed: u64, change: usize, after: Deadzone<f64>) -> (Vec<f64>, Vec<f64>) {
    let before = Deadzone {
        b_l: -25.0,
        b_r: 20.0,
        m_l: 5.42182e-3,
        m_r: 3.72946e-3,
    };
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (a1, a2, a3) = (-1.869, 0.9976, -0.1284);
    let (mut u, mut y) = (vec![0.0f64; n], vec![0.0f64; n]);
    let mut level: f64 = 0.0;
    for k in 0..n {
        if k % 40 == 0 {
            level = f64::from(rng.gen_range(-255i32..=255));
            if k > 3 && y[k - 1].abs() > 80.0 {
                level = -level.abs() * y[k - 1].signum();
            }
        }
        u[k] = level;
        if k >= 3 {
            let dz = if k > change { after } else { before };
            y[k] = -a1 * y[k - 1] - a2 * y[k - 2] - a3 * y[k - 3]
                + dz.apply(u[k - 1])
                + 0.01 * gauss(&mut rng);
        }
    }
    (u, y)
}

/// The first alarm of the default detector (warm-up 2000, calibration 3000) on the estimator's errors.
fn first_alarm(u: &[f64], y: &[f64]) -> Option<usize> {
    let mut est = PaperHrls::<f64>::new(HammersteinSettings::paper()).unwrap();
    let mut det = Cusum::new(
        2000,
        3000,
        Cusum::<f64>::DEFAULT_DRIFT,
        Cusum::<f64>::DEFAULT_THRESHOLD,
    )
    .unwrap();
    for (k, (uk, yk)) in u.iter().zip(y).enumerate() {
        if let Some(eps) = est.update(*uk, *yk).unwrap() {
            if let CusumStatus::Alarm(_) = det.update(eps).unwrap() {
                return Some(k);
            }
        }
    }
    None
}

#[test]
fn a_valve_change_is_flagged_within_a_few_hundred_samples() {
    // Large: b_r 20 → 28 counts, b_l −25 → −33, both slopes −10 %: at u = 100 the valve gives 0.063 mm
    // (6 σ) less per sample than the model predicts. Small: b_r 20 → 23, b_l −25 → −28, slopes −3 %:
    // 0.019 mm (2 σ) at u = 100, less at smaller commands.
    let change = |db: f64, slope: f64| Deadzone {
        b_l: -25.0 - db,
        b_r: 20.0 + db,
        m_l: slope * 5.42182e-3,
        m_r: slope * 3.72946e-3,
    };
    for (what, after) in [("large", change(8.0, 0.9)), ("small", change(3.0, 0.97))] {
        for seed in [1, 2, 3] {
            let at = 25_000;
            let (u, y) = record(40_000, seed, at, after);
            let k = first_alarm(&u, &y).expect("the change must be flagged");
            assert!(
                k >= at,
                "{what}, seed {seed}: false alarm at {k} before the change"
            );
            assert!(
                k < at + 300,
                "{what}, seed {seed}: flagged {} samples after the change",
                k - at
            );
            eprintln!(
                "{what} change, seed {seed}: flagged {} samples after it",
                k - at
            );
        }
    }
}

#[test]
fn a_stationary_record_of_50000_samples_raises_no_alarm() {
    let same = Deadzone {
        b_l: -25.0,
        b_r: 20.0,
        m_l: 5.42182e-3,
        m_r: 3.72946e-3,
    };
    for seed in [4, 5] {
        let (u, y) = record(50_000, seed, usize::MAX, same);
        assert_eq!(first_alarm(&u, &y), None, "seed {seed}");
    }
}

/// erfc: 1 − the Maclaurin series of erf for x < 2 (terms below e⁴, so no cancellation), the
/// continued fraction e^(−x²)/√π · 1/(x + (1/2)/(x + 1/(x + (3/2)/(x + …)))) beyond (tails to full
/// relative precision, which the large-threshold ARL needs).
fn erfc(x: f64) -> f64 {
    if x < 2.0 {
        let (mut term, mut sum) = (x, x);
        for n in 1..60 {
            term *= -x * x / n as f64;
            sum += term / (2 * n + 1) as f64;
        }
        return 1.0 - sum * 2.0 / std::f64::consts::PI.sqrt();
    }
    let mut f = x;
    for k in (1..200).rev() {
        f = x + (k as f64 / 2.0) / f;
    }
    (-x * x).exp() / (std::f64::consts::PI.sqrt() * f)
}

/// ARL of the CUSUM on z ~ χ²₁ from g = 0 (Brook & Evans: m states of width w, absorbing above h),
/// solving (I − Q) L = 1 by Gaussian elimination.
#[allow(clippy::needless_range_loop)] // the textbook index loops of the elimination
fn markov_arl(nu: f64, h: f64, m: usize) -> f64 {
    // P(z > x) for z ~ χ²₁.
    let sf = |x: f64| if x > 0.0 { erfc((x / 2.0).sqrt()) } else { 1.0 };
    let w = 2.0 * h / (2.0 * m as f64 - 1.0);
    let mut a = vec![vec![0.0; m + 1]; m];
    for i in 0..m {
        let ci = i as f64 * w;
        for j in 0..m {
            let q = if j == 0 {
                1.0 - sf(w / 2.0 - ci + nu)
            } else {
                sf((j as f64 - 0.5) * w - ci + nu) - sf((j as f64 + 0.5) * w - ci + nu)
            };
            a[i][j] = f64::from(u8::from(i == j)) - q;
        }
        a[i][m] = 1.0;
    }
    for c in 0..m {
        let p = (c..m)
            .max_by(|&r, &s| a[r][c].abs().total_cmp(&a[s][c].abs()))
            .unwrap();
        a.swap(c, p);
        for r in 0..m {
            if r != c {
                let f = a[r][c] / a[c][c];
                for k in c..=m {
                    a[r][k] -= f * a[c][k];
                }
            }
        }
    }
    a[0][m] / a[0][0]
}

// ν = 2, h = 6 on white N(0, 1) errors with σ² known: the mean run length of 4000 simulated runs is
// within 5 % of the Markov-chain value (≈ 131; its standard error is ≈ 2 %). The same Markov chain gives
// the table of the module documentation.
#[test]
fn run_length_matches_the_markov_chain() {
    let want = markov_arl(2.0, 6.0, 300);
    assert!((want - 131.0).abs() < 1.0, "{want}");
    let mut rng = ChaCha8Rng::seed_from_u64(99);
    let runs = 4000;
    let mut total = 0usize;
    for _ in 0..runs {
        let mut d = Cusum::with_variance(1.0, 2.0, 6.0).unwrap();
        let mut k = 0;
        loop {
            k += 1;
            if let CusumStatus::Alarm(_) = d.update(gauss(&mut rng)).unwrap() {
                break;
            }
        }
        total += k;
    }
    let got = total as f64 / runs as f64;
    assert!(
        (got / want - 1.0).abs() < 0.05,
        "simulated ARL {got}, Markov chain {want}"
    );
    // The default's false-alarm rate, as documented: ARL ≈ 2.8e7 samples.
    let default = markov_arl(3.0, 30.0, 300);
    assert!((default / 2.76e7 - 1.0).abs() < 0.02, "{default:e}");
}
