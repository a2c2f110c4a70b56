//! The record, regressor and settings shared by the benchmarks `rls` (criterion) and `interleaved`.
//!
//! Data: 1e6 samples of the second-order ARX system
//! y(t) = 1.5 y(t−1) − 0.7 y(t−2) + u(t−1) + 0.5 u(t−2) + 0.1 e(t), with u, e white N(0, 1). Regressors
//! φ(t) = [−y(t−1), …, −y(t−na), u(t−1), …, u(t−nb)], the peer's own regressor for (NA, NB, NK = 1):
//! n = 4 is (na, nb) = (2, 2), n = 9 is (4, 5). λ = 0.98, P(0) = 1000 I for both estimators.

use ipa_embedded::{Float, Form, Rls};
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
