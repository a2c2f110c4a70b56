//! The record, regressor and settings shared by the benchmarks `rls` (criterion) and `interleaved`.
//!
//! Data: 1e6 samples of the second-order ARX system
//! y(t) = 1.5 y(t−1) − 0.7 y(t−2) + u(t−1) + 0.5 u(t−2) + 0.1 e(t), with u, e white N(0, 1). Regressors
//! φ(t) = [−y(t−1), …, −y(t−na), u(t−1), …, u(t−nb)], the peer's own regressor for (NA, NB, NK = 1):
//! n = 4 is (na, nb) = (2, 2), n = 9 is (4, 5). λ = 0.98, P(0) = 1000 I for both estimators.
//! The Hammerstein estimator's record: [`hammerstein_record`].

use ipa_embedded::{Deadzone, Float, Form, Rls};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// Samples in the record.
pub const SAMPLES: usize = 1_000_000;
/// λ (ρ): the forgetting factor of both estimators.
pub const LAMBDA: f64 = 0.98;
/// p0: P(0) = p0 I for both estimators.
pub const P0: f64 = 1000.0;

/// (u, y) of the second-order ARX system (module documentation).
pub fn arx_record() -> (Vec<f64>, Vec<f64>) {
    let mut rng = ChaCha8Rng::seed_from_u64(28);
    let mut u = vec![0.0; SAMPLES];
    let mut y = vec![0.0; SAMPLES];
    for t in 0..SAMPLES {
        u[t] = StandardNormal.sample(&mut rng);
        let e: f64 = StandardNormal.sample(&mut rng);
        if t >= 2 {
            y[t] = 1.5 * y[t - 1] - 0.7 * y[t - 2] + u[t - 1] + 0.5 * u[t - 2] + 0.1 * e;
        }
    }
    (u, y)
}

/// φ(t) = [−y(t−1), …, −y(t−NA), u(t−1), …, u(t−NB)] (t ≥ max(NA, NB)).
#[inline(always)]
pub fn regressor<F: Float, const NA: usize, const NB: usize, const P: usize>(
    u: &[F],
    y: &[F],
    t: usize,
) -> [F; P] {
    let mut phi = [F::ZERO; P];
    for (i, v) in phi.iter_mut().enumerate() {
        *v = if i < NA {
            -y[t - 1 - i]
        } else {
            u[t - 1 - (i - NA)]
        };
    }
    phi
}

/// Our estimator with the benchmark's settings, in `form`, with the trace bound `trace` if any.
pub fn new_rls<F: Float, const P: usize>(form: Form, trace: Option<f64>) -> Rls<F, P> {
    let mut est = Rls::<F, P>::new(P, F::from_f64(LAMBDA), F::from_f64(P0))
        .unwrap()
        .with_form(form);
    if let Some(t) = trace {
        est = est.with_max_trace(F::from_f64(t)).unwrap();
    }
    est
}

/// (u in counts, y in mm) of a Hammerstein plant: deadzone b_l = −25, b_r = 20 counts, ARX(3, 1, 1)
/// with poles at 0.9, 0.8, 0.5, staircase input held 10 samples, output noise 0.01 mm.
pub fn hammerstein_record() -> (Vec<f64>, Vec<f64>) {
    let mut rng = ChaCha8Rng::seed_from_u64(29);
    let dz = Deadzone {
        b_l: -25.0,
        b_r: 20.0,
        m_l: 0.05,
        m_r: 0.04,
    };
    // (1 − 0.9 q⁻¹)(1 − 0.8 q⁻¹)(1 − 0.5 q⁻¹) = 1 − 2.2 q⁻¹ + 1.57 q⁻² − 0.36 q⁻³.
    let (a1, a2, a3) = (-2.2, 1.57, -0.36);
    let mut u = vec![0.0; SAMPLES];
    let mut y = vec![0.0; SAMPLES];
    let mut level = 0.0;
    for t in 0..SAMPLES {
        if t % 10 == 0 {
            let g: f64 = StandardNormal.sample(&mut rng);
            level = (g * 120.0).round().clamp(-255.0, 255.0);
        }
        u[t] = level;
        if t >= 3 {
            let e: f64 = StandardNormal.sample(&mut rng);
            y[t] = -a1 * y[t - 1] - a2 * y[t - 2] - a3 * y[t - 3] + dz.apply(u[t - 1]) + 0.01 * e;
        }
    }
    (u, y)
}
